"""Residual characterisation of a fitted model on a dataset (issue 12 research)."""
import json, sys, math
from pathlib import Path
import numpy as np
from scipy import signal
from research.common import load
from tuner.identification.fit import validation_run

def residuals(d, params, model="lumped"):
    rows = []
    for p, s in zip([*d["prep_id"], *d["prep_val"]], [*d["sig_id"], *d["sig_val"]]):
        sim, _ = validation_run(model, params, s, "native")
        rows.append(dict(name=s.name, t=s.time, x=s.stroke, v=s.stroke_velocity, f=s.force, sim=sim, m=s.mask))
    return rows

def table(rows, key, edges, fn, label):
    print(f"-- residual rms vs {label}")
    for lo, hi in zip(edges[:-1], edges[1:]):
        se = n = 0
        for r in rows:
            q = fn(r)
            sel = r["m"] & (q >= lo) & (q < hi)
            e = (r["f"] - r["sim"])[sel]
            se += float(e @ e); n += e.size
        if n:
            print(f"   [{lo:9.4g},{hi:9.4g})  n={n:6d}  rms {math.sqrt(se/n):7.1f} N   share of SSE {se:.3g}")

def main():
    d = load(Path(sys.argv[1]))
    params = json.loads(Path(sys.argv[2]).read_text())
    rows = residuals(d, params)
    tot = sum(float(((r["f"]-r["sim"])[r["m"]])**2 @ np.ones(r["m"].sum())) for r in rows)
    for r in rows:
        e = (r["f"] - r["sim"])[r["m"]]
        x, v, f = r["x"][r["m"]], r["v"][r["m"]], r["f"][r["m"]]
        # linear regression of the residual on [1, x, v, f, |f|, df/dt]
        dfdt = np.gradient(r["sim"], r["t"])[r["m"]]
        X = np.column_stack([np.ones_like(x), x - x.mean(), v, r["sim"][r["m"]], np.abs(r["sim"][r["m"]]), dfdt])
        names = ["1", "x", "v", "Fsim", "|Fsim|", "dFsim/dt"]
        shares = []
        for j in range(X.shape[1]):
            g = X[:, j]; shares.append((g @ e) ** 2 / (g @ g * (e @ e)))
        coef, *_ = np.linalg.lstsq(X, e, rcond=None)
        rres = e - X @ coef
        print(f"{r['name']:24s} rms {np.sqrt(np.mean(e**2)):6.1f} N  peak F {np.abs(f).max():7.0f}  stroke p2p {1e3*np.ptp(x):5.1f} mm  "
              f"vmax {1e3*np.abs(v).max():6.1f} mm/s  mean {e.mean():6.1f}  "
              + " ".join(f"{n}:{s:.2f}" for n, s in zip(names, shares)) + f"  joint-left {np.sqrt(np.mean(rres**2)):.1f}")
    # bins
    table(rows, "v", np.array([-1, -0.05, -0.02, -0.01, -0.005, -0.002, 0, 0.002, 0.005, 0.01, 0.02, 0.05, 1]),
          lambda r: r["v"], "stroke velocity [m/s]")
    table(rows, "F", np.array([-4e4, -15e3, -10e3, -5e3, -2e3, 0, 2e3, 5e3, 10e3, 15e3, 4e4]),
          lambda r: r["sim"], "simulated force [N]")
    def since_rev(r):
        v = r["v"]; out = np.zeros_like(v); last = r["t"][0] - 10
        for i in range(1, len(v)):
            if np.sign(v[i]) != np.sign(v[i-1]): last = r["t"][i]
            out[i] = r["t"][i] - last
        return out
    table(rows, "trev", np.array([0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 100]), since_rev, "time since velocity reversal [s]")
    # sign of force rate (loading vs unloading)
    table(rows, "load", np.array([-2, -0.5, 0.5, 2]), lambda r: np.sign(np.gradient(r["sim"], r["t"]) * r["sim"]), "sign(F dF/dt) (+ loading)")
    # spectra
    print("-- residual power by band (all tests)")
    bands = [(0, 0.5), (0.5, 1), (1, 2), (2, 5), (5, 10), (10, 20), (20, 100)]
    for r in rows:
        e = np.where(r["m"], r["f"] - r["sim"], 0.0)
        fq, P = signal.periodogram(e, fs=1 / np.median(np.diff(r["t"])))
        fq2, Pf = signal.periodogram(np.where(r["m"], r["f"], 0), fs=1 / np.median(np.diff(r["t"])))
        tot = P.sum()
        print(f"{r['name']:24s} " + " ".join(f"{a}-{b}Hz:{P[(fq>=a)&(fq<b)].sum()/tot:.2f}" for a, b in bands)
              + "  | force: " + " ".join(f"{Pf[(fq>=a)&(fq<b)].sum()/Pf.sum():.2f}" for a, b in bands))
    np.savez("/tmp/form/resid_rows.npz", **{f"{r['name']}__{k}": r[k] for r in rows for k in ("t","x","v","f","sim","m")})

if __name__ == "__main__":
    main()
