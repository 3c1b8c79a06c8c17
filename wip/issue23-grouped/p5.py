import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
from types import SimpleNamespace as NS
from derive.control.grouped import GroupedModel
from derive.control import grouped_cells as gc
from derive.control.certificate import _spectral_norm
(coef, F), spans = fourier()
full = NS(fourier=(coef, F), spans=spans, deps=[NS(index=i + 1) for i in range(6)], m=6, n=7)
W = np.load("/tmp/cert/W_panda.npy")
g = GroupedModel(full, (0,1,2,4), np.ones(7))
prep = gc._Prepared(g, W)
v = 1.0
print("nM max", prep.nM.max(axis=0).round(2)); print("nY max", prep.nY.max(axis=0).round(2))
rng = np.random.default_rng(1)
lo = np.array([s[0] for s in g.spans]); hi = np.array([s[1] for s in g.spans])
c = lo + (hi - lo) * rng.random((8, 4))
M, Y = prep.evaluate(g, c)
Y0, D = Y[:, :, 0], Y[:, :, 1:]
G = np.einsum("pvac,pvbc->pvab", Y0, Y0)
X = np.einsum("pvac,pvjbc->pvjab", Y0, D)
Lj = v * (M[:, :, 1:] + X + np.swapaxes(X, -1, -2))
const = (prep.T @ (W + W.T) @ prep.T.T)[None] - v * (prep.Pt[None] + prep.rounding[:, None, None] * np.eye(7)[None])
C = const[None] - v * (M[:, :, 0] + G)
lam = np.linalg.eigvalsh(C)[..., 0]
print("lam min per pt", lam.min(1).round(3))
print("||Pt||", np.linalg.norm(prep.Pt, 2), "Yn", np.sqrt((Y0**2).sum((-1,-2))).max(), "Dn", np.sqrt((D**2).sum((-1,-2))).max((0,1)))
print("||Lj|| max", np.linalg.norm(Lj, 2, axis=(-2,-1)).max((0,1)))
for r in (0.4, 0.2, 0.1, 0.05):
    h = np.full((8, 4), r)
    Dn = np.sqrt((D ** 2).sum(axis=(-1, -2))); rD = np.einsum("pj,pvj->pv", h, Dn)
    Yn = np.sqrt((Y0 ** 2).sum(axis=(-1, -2)))
    rr = 0.5 * np.einsum("pj,pk->pjk", h, h)
    rM = np.einsum("pjk,vjk->pv", rr, prep.nM); rY = np.einsum("pjk,vjk->pv", rr, prep.nY)
    lin = _spectral_norm(np.einsum("pj,pvjab->pvab", h, np.abs(Lj)))
    print(r, "lin", lin.max().round(3), "quad", (rD**2).max().round(3), "cross", (2*(Yn+rD)*rY).max().round(3), "rM", rM.max().round(3))
