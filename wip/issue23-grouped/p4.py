import sys; sys.path.insert(0,'/tmp/cert2')
from common import *
from types import SimpleNamespace as NS
from derive.control.grouped import GroupedModel
from derive.control.grouped_cells import decide_grouped
(coef, F), spans = fourier()
full = NS(fourier=(coef, F), spans=spans, deps=[NS(index=i + 1) for i in range(6)], m=6, n=7)
W = np.load("/tmp/cert/W_panda.npy")
inner = tuple(int(x) for x in sys.argv[1].split(","))
g = GroupedModel(full, inner, np.ones(7))
for v in map(float, sys.argv[2:]):
    t = time.process_time()
    d = decide_grouped(g, W, v, budget=int(os.environ.get("BUDGET", "3000")))
    print(v, v / 3.923, d.verdict, d.cells, d.margin, d.low, time.process_time() - t, flush=True)
