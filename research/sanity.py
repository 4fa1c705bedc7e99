import json, sys, time, math
from pathlib import Path
import numpy as np
from research.common import load
from research.chain import from_lumped, sim_signals
d = load(Path("/tmp/form/data_s1"))
base = json.loads(Path("/tmp/form/base_s1/base_params.json").read_text())
prm = from_lumped(base)
for sub in (1, 5, 20):
    t0 = time.perf_counter()
    se = n = 0
    for s in d["sig_id"]:
        f = sim_signals(s, prm, "none", "inner", sub)
        r = (s.force - f)[s.mask]; se += r @ r; n += r.size
    print(sub, math.sqrt(se / n), time.perf_counter() - t0)
