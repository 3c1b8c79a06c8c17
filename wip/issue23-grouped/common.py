import time, numpy as np, itertools, pickle, os
import derive
from pathlib import Path
from derive.model.spec import load_arm
from derive.control import certificate as cert
def panda():
    d = derive.derive(load_arm(Path("/work/wt/cert2/tests/data/urdf/panda.toml")))
    return d, cert.inertia_model(d)
def fourier():
    p = "/tmp/cert2/fourier.pkl"
    if os.path.exists(p):
        return pickle.load(open(p, "rb"))
    d, model = panda()
    out = (model.fourier, model.spans)
    pickle.dump(out, open(p, "wb"))
    return out
