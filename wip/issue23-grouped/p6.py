import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
from types import SimpleNamespace as NS
from derive.control.grouped import GroupedModel
(coef, F), spans = fourier()
full = NS(fourier=(coef, F), spans=spans, deps=[NS(index=i + 1) for i in range(6)], m=6, n=7)
inner = (0, 1, 2, 4)
g = GroupedModel(full, inner, np.ones(7))
rng = np.random.default_rng(5)
lo = np.array([s[0] for s in spans]); hi = np.array([s[1] for s in spans])
q = lo + (hi - lo) * rng.random((100, 6))
B = g.bound(q[:, list(inner)])                       # P x V x n x n
E = np.exp(1j * (q @ F.T))
Jd = np.einsum("pk,vk,kab->pvab", E, 1j * (g.signs @ F.T), coef, optimize=True).real
gap = np.linalg.eigvalsh(B - Jd)[..., 0]
print("min eigenvalue of B - J' over 100 states x 64 vertices:", gap.min(), " (B - J' must be >= 0)")
