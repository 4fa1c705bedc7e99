"""Fit every candidate model form on a twin-tube dataset; identification and held-out RMSE vs noise.

python -m research.candidates DATA BASE_PARAMS_JSON OUT_JSON cand1,cand2,...   (cand = kind:attach)"""
import itertools
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from research.chain import Form, from_lumped, residual, rmse, fit, UNITS

START = {"kgas": [1e3, 3e3], "LR": [0.1, 0.3], "LC": [0.1, 0.3], "k2": [5e6, 2e7, 6e7], "c2": [3e4, 3e5, 3e6], "fy": [1e3, 4e3, 1e4], "fy_pos": [1e3, 5e3], "fy_neg": [1e3, 5e3]}


def run(data, base_json, out_json, cands, sub_fit=2, max_nfev=60):
    from research.common import load
    d = load(Path(data))
    base = json.loads(Path(base_json).read_text())
    res = json.loads(Path(out_json).read_text()) if Path(out_json).exists() else {}
    prm0 = from_lumped(base)
    axes = {k: v for k, v in base.items() if k.startswith(("Fc_v", "Fk_x"))}
    for cand in cands:
        kind, attach = (cand.split(":") + ["inner"])[:2]
        form = Form(axes, kind, attach)
        t0 = time.perf_counter()
        zb = form.from_params({**prm0, **{n: START[n][0] for n in form.extra}})
        # start of the extra parameters: best of a small grid with the base fixed
        best = (math.inf, zb)
        if form.extra:
            for combo in itertools.product(*[START[n] for n in form.extra]):
                z = zb.copy()
                z[-len(form.extra):] = np.log(combo)
                r = rmse(form, z, d["sig_id"], sub_fit)
                if r < best[0]:
                    best = (r, z)
        z0 = best[1]
        z, el, sol = fit(form, z0, d["sig_id"], max_nfev=max_nfev, sub=sub_fit)
        rid, rval = rmse(form, z, d["sig_id"], 5), rmse(form, z, d["sig_val"], 5)
        prm = form.to_params(z)
        row = {"id": rid, "val": rval, "noise": d["noise"], "id_x": rid / d["noise"], "val_x": rval / d["noise"],
               "elapsed_s": time.perf_counter() - t0, "nfev": int(sol.nfev), "status": sol.message,
               "extra": {n: prm[n] for n in form.extra}, "units": {n: UNITS[n] for n in form.extra},
               "kM": prm["kM"], "cM": prm["cM"], "fc_f": list(prm["fc_f"]), "fk_f": list(prm["fk_f"]),
               "fc_x": list(prm["fc_x"]), "fk_x": list(prm["fk_x"])}
        res[cand] = row
        print(f"{cand:22s} id {rid:7.1f} N ({rid / d['noise']:5.1f}x)  val {rval:7.1f} N ({rval / d['noise']:5.1f}x)  "
              f"{row['elapsed_s']:.0f} s  nfev {sol.nfev}  extra {row['extra']}  kM {prm['kM']:.3g} cM {prm['cM']:.3g}", flush=True)
        Path(out_json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    run(sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4].split(","))
