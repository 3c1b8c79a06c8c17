import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
(coef, F), spans = fourier()
W = np.load("/tmp/cert/W_panda.npy"); S = W + W.T
Li = np.linalg.inv(np.linalg.cholesky(S))
keep = np.abs(coef).reshape(len(coef), -1).max(1) > 1e-14
coef, F = coef[keep], F[keep]
inner = [int(x) for x in sys.argv[1].split(",")]
outer = [k for k in range(6) if k not in inner]
groups = {}
for i, g in enumerate(map(tuple, F[:, outer])): groups.setdefault(g, []).append(i)
reps = [g for g in groups if any(x != 0 for x in g) and next(x for x in g if x != 0) > 0]
zero = groups[tuple([0] * len(outer))]
signs = np.array(list(itertools.product((1.0, -1.0), repeat=6)))
fs = F @ signs.T
rng = np.random.default_rng(3)
lo = np.array([s[0] for s in spans]); hi = np.array([s[1] for s in spans])
npts = int(sys.argv[2])
def Zs(q):
    base = coef[None] * np.exp(1j * (q[:, inner] @ F[:, inner].T))[:, :, None, None]
    Mz = np.einsum("kv,pkab->pvab", 1j * fs[zero], base[:, zero]).real
    Z = np.stack([np.einsum("kv,pkab->pvab", 1j * fs[groups[g]], base[:, groups[g]]) for g in reps], 2)
    return Mz, Z
q = lo + (hi - lo) * rng.random((npts, 6))
Mz, Z = Zs(q)
qt = lo + (hi - lo) * rng.random((npts, 6))
Mzt, Zt = Zs(qt)
Jd = np.einsum("kv,pkab->pvab", 1j * fs, coef[None] * np.exp(1j * (qt @ F.T))[:, :, None, None]).real
print("groups", len(reps), "exact sup at test pts", 1 / np.linalg.eigvalsh(Li @ Jd @ Li.T)[..., -1].max())
def sq(M):
    w, V = np.linalg.eigh(M); return np.einsum("...ij,...j,...kj->...ik", V, np.sqrt(np.maximum(w, 0)), V)
ZZv = np.einsum("pvgab,pvgcb->vgac", Z, Z.conj()).real / npts
ZZg = ZZv.mean(0)
for name, ZZ in (("per g,v", ZZv), ("per g", ZZg[None])):
    for fac in (1.5, 2.0, 3.0):
        P = fac * sq(ZZ) + 1e-6 * np.eye(7)
        Pi = np.linalg.inv(P)
        B = (np.einsum("pvgab,vgbc,pvgdc->pvgad", Zt, Pi, Zt.conj()).real + P[None]).sum(2)
        print(name, fac, 1 / np.linalg.eigvalsh(Li @ (Mzt + B) @ Li.T)[..., -1].max(), flush=True)
