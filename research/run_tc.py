"""Fit the two-chamber form (optionally with a denser damping table) on a dataset.

python -m research.run_tc DATA BASE_PARAMS_JSON OUT_JSON [densify=1|2|3] [label]"""
import json, math, sys, time
from pathlib import Path
import numpy as np
from research.common import load
from research.chain import from_lumped
from research.twochamber import TCForm, rmse, fit


def densify(xs, k):
    pos = np.sort(xs[xs > 0])
    if k == 1:
        d = pos
    else:
        edges = np.concatenate([[0.0], pos])
        d = np.concatenate([lo + (hi - lo) * np.arange(1, k + 1) / k for lo, hi in zip(edges[:-1], edges[1:])])
    return np.concatenate([-d[::-1], d])


def main(data, base_json, out_json, k=1, label=None, options="", start=None):
    d = load(Path(data))
    b = from_lumped(json.loads(Path(base_json).read_text()))
    fcx = densify(b["fc_x"], k)
    form = TCForm(fcx, [o for o in options.split('+') if o])
    prm = {"fc_f": np.interp(fcx, b["fc_x"], b["fc_f"]), "kR": 2.5e7, "kC": 7e7, "a": 1 / 3, "kM": 3e7, "cM": 5e4}
    prm.update({"LR": 0.1, "LC": 0.1, "crack_p": 30.0, "crack_f": 60.0, "air": 1.0, "fres": 1000.0, "mass": 2.0, "kgas": 1000.0, "ffric": 50.0, "ffric_out": 50.0})
    if start == "neutral":  # a start that knows nothing of the twin-tube's numbers
        prm.update({"kR": 1.5e7, "kC": 1.5e7, "a": 0.5, "kM": 2e8, "cM": 1e5, "LR": 0.3, "LC": 0.3, "air": 0.5,
                    "fres": 2000.0})
    elif start:  # OUT_JSON:label of an earlier fit
        f, lab = start.split(":")
        s = json.loads(Path(f).read_text())[lab]["params"]
        prm.update({k2: s[k2] for k2 in ("kR", "kC", "a", "kM", "cM", "LR", "LC", "crack_p", "crack_f", "air", "fres", "mass", "kgas", "ffric", "ffric_out") if k2 in s})
        prm["fc_f"] = np.interp(fcx, s["fc_x"], s["fc_f"])
    t0 = time.perf_counter()
    z, el, sol = fit(form, form.from_params(prm), d["sig_id"], max_nfev=150, sub=2)
    p = form.to_params(z)
    rid, rval = rmse(form, z, d["sig_id"], 4), rmse(form, z, d["sig_val"], 4)
    label = label or f"twochamber_x{k}"
    print(f"{label:24s} id {rid:7.1f} N ({rid / d['noise']:5.1f}x)  val {rval:7.1f} N ({rval / d['noise']:5.1f}x)  "
          f"{time.perf_counter() - t0:.0f} s nfev {sol.nfev}  kR {p['kR']:.3g} kC {p['kC']:.3g} a {p['a']:.3f} "
          f"kM {p['kM']:.3g} cM {p['cM']:.3g}  params {len(z)}  " + " ".join(f"{n} {p[n]:.4g}" for n in form.extra), flush=True)
    res = json.loads(Path(out_json).read_text()) if Path(out_json).exists() else {}
    res[label] = {"id": rid, "val": rval, "noise": d["noise"], "elapsed_s": time.perf_counter() - t0, "n_params": len(z),
                  "params": {kk: (list(map(float, v)) if hasattr(v, "__len__") else float(v)) for kk, v in p.items()}}
    Path(out_json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    a = sys.argv[1:]
    main(a[0], a[1], a[2], int(a[3]) if len(a) > 3 else 1, a[4] if len(a) > 4 else None, a[5] if len(a) > 5 else "",
         a[6] if len(a) > 6 else None)
