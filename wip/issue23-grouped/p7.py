import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
from types import SimpleNamespace as NS
from derive.control.grouped import GroupedModel
from derive.control import grouped_cells as gc
(coef, F), spans = fourier()
full = NS(fourier=(coef, F), spans=spans, deps=[NS(index=i + 1) for i in range(6)], m=6, n=7)
W = np.load("/tmp/cert/W_panda.npy")
g = GroupedModel(full, (0,1,2,4), np.ones(7))
prep = gc._Prepared(g, W)
T = prep.T
rng = np.random.default_rng(2)
lo = np.array([s[0] for s in g.spans]); hi = np.array([s[1] for s in g.spans])
c = lo + (hi - lo) * rng.random((32, 4))
h = 1e-3
B0 = g.bound(c)
out = np.zeros(4)
for j in range(4):
    e = np.zeros(4); e[j] = h
    d2 = (g.bound(c + e) - 2 * B0 + g.bound(c - e)) / h ** 2
    d2 = np.einsum("ab,pvbc,dc->pvad", T, d2, T)
    out[j] = np.linalg.norm(d2, 2, axis=(-2, -1)).max()
print("max ||d2 B~/dq_j^2|| at 32 points x 64 vertices:", out.round(3))
print("the WIP cell test's bound of the same (2 (|Y|+0) nY_jj + nM_jj, max over vertices):",
      (2 * 0.24 * prep.nY.max(0).diagonal() + prep.nM.max(0).diagonal()).round(3))
