import json, math, sys
from pathlib import Path
import numpy as np
from research.common import load
from research.twochamber import sim_signals

def main(data, res_json, label):
    d = load(Path(data))
    p = json.loads(Path(res_json).read_text())[label]["params"]
    p = {k: (np.array(v) if isinstance(v, list) else v) for k, v in p.items()}
    rows = []
    for s in d["sig_id"] + d["sig_val"]:
        sim = sim_signals(s, p, 4)
        e = (s.force - sim)[s.mask]; x = s.stroke[s.mask]; v = s.stroke_velocity[s.mask]
        rows.append((s.name, e, x, v, sim[s.mask], s.force[s.mask]))
        X = np.column_stack([np.ones_like(x), x - x.mean(), np.abs(x - x.mean()), v, sim[s.mask]])
        c, *_ = np.linalg.lstsq(X, e, rcond=None)
        print(f"{s.name:24s} rms {np.sqrt(np.mean(e**2)):6.1f}  mean {e.mean():6.1f}  stroke range {1e3*x.min():6.1f}..{1e3*x.max():5.1f} mm  "
              f"after [1,x,|x|,v,F] regression {np.sqrt(np.mean((e - X @ c)**2)):6.1f}")
    E = np.concatenate([r[1] for r in rows]); V = np.concatenate([r[3] for r in rows]); Xs = np.concatenate([r[2] for r in rows])
    F = np.concatenate([r[4] for r in rows])
    for lab, q, edges in (("v mm/s", 1e3 * V, [-200, -30, -10, -5, -2.5, 0, 2.5, 5, 10, 30, 200]),
                          ("x mm", 1e3 * Xs, [-70, -30, -10, -3, 0, 3, 10, 30, 70]),
                          ("F kN", F / 1e3, [-30, -15, -5, -2, 0, 2, 5, 15, 30])):
        print("-- vs", lab)
        for lo, hi in zip(edges[:-1], edges[1:]):
            sel = (q >= lo) & (q < hi)
            if sel.sum():
                print(f"   [{lo:6g},{hi:6g})  n {sel.sum():5d}  rms {np.sqrt(np.mean(E[sel]**2)):6.1f}  mean {E[sel].mean():7.1f}")

if __name__ == "__main__":
    main(*sys.argv[1:4])
