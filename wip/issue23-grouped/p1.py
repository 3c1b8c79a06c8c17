import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
(coef, F), spans = fourier()
print(coef.shape, F.shape, spans)
W = np.load("/tmp/cert/W_panda.npy")
S = W + W.T
Li = np.linalg.inv(np.linalg.cholesky(S))
n = 7
keep = np.abs(coef).reshape(len(coef), -1).max(1) > 1e-14
coef, F = coef[keep], F[keep]
print("nonzero terms", len(F))
def absm(X):
    w, V = np.linalg.eigh(X); return np.einsum("...ij,...j,...kj->...ik", V, np.abs(w), V)
inner = [int(x) for x in sys.argv[1].split(",")]
outer = [k for k in range(6) if k not in inner]
groups = {}
for i, g in enumerate(map(tuple, F[:, outer])): groups.setdefault(g, []).append(i)
reps = [g for g in groups if any(x != 0 for x in g) and next(x for x in g if x != 0) > 0]
zero = groups[tuple([0] * len(outer))]
print("groups", len(reps))
signs = np.array(list(itertools.product((1.0, -1.0), repeat=6)))
fs = F @ signs.T  # K x V
rng = np.random.default_rng(3)
npts = int(sys.argv[2])
q = rng.uniform(-np.pi, np.pi, (npts, 6))
# Z_g at points: P x V x n x n complex
def Zs(q):
    base = coef[None] * np.exp(1j * (q[:, inner] @ F[:, inner].T))[:, :, None, None]  # P K n n
    Mz = np.einsum("kv,pkab->pvab", 1j * fs[zero], base[:, zero]).real
    Z = np.stack([np.einsum("kv,pkab->pvab", 1j * fs[groups[g]], base[:, groups[g]]) for g in reps], 2)  # P V G n n
    return Mz, Z
Mz, Z = Zs(q)
X, Y = Z.real, Z.imag
U = 2 * (absm(X) + absm(Y)).sum(2)
top = np.linalg.eigvalsh(Li @ (Mz + U) @ Li.T)[..., -1].max()
print("pointwise grouped sup", 1 / top)
# exact
Jd = np.einsum("kv,pkab->pvab", 1j * fs, coef[None] * np.exp(1j * (q @ F.T))[:, :, None, None]).real
print("exact sup at pts", 1 / np.linalg.eigvalsh(Li @ Jd @ Li.T)[..., -1].max())
# global P per (g, v): sqrt of mean Re(Z Z^H) over points
ZZ = np.einsum("pvgab,pvgcb->vgac", Z, Z.conj()).real / npts
for fac in (1.0, 1.5, 2.0):
    w, V = np.linalg.eigh(ZZ); P = fac * np.einsum("...ij,...j,...kj->...ik", V, np.sqrt(np.maximum(w, 0)) + 1e-9, V)
    Pi = np.linalg.inv(P)
    B = (np.einsum("pvgab,vgbc,pvgdc->pvgad", Z, Pi, Z.conj()).real + P[None]).sum(2)
    print("global P", fac, 1 / np.linalg.eigvalsh(Li @ (Mz + B) @ Li.T)[..., -1].max())
