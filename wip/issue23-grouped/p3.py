import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
from types import SimpleNamespace as NS
from derive.control.grouped import GroupedModel
(coef, F), spans = fourier()
full = NS(fourier=(coef, F), spans=spans, deps=[NS(index=i + 1) for i in range(6)], m=6, n=7)
W = np.load("/tmp/cert/W_panda.npy")
inner = tuple(int(x) for x in sys.argv[1].split(","))
t = time.process_time()
g = GroupedModel(full, inner, np.ones(7))
print("built", time.process_time() - t, [len(x[0]) for x in g.groups], len(g.zero[0]))
t = time.process_time()
print("sup", g.supremum(W, int(sys.argv[2])), time.process_time() - t)
