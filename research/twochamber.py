"""Two-chamber lumped form (research/c/twochamber.c): Python wrapper, parametrization, fit.

Parameters (SI): the damping table Fc,O as in the lumped model (rebound half = piston valve,
compression half = foot valve through the area ratio), kR [N/m] rebound-chamber stiffness,
kC [N/m] compression-chamber (sealed) stiffness, a [-] = annulus / piston area, kM [N/m], cM [N s/m]
silent blocks (both in series). Check valves: linear, CCHK [N s/m] fixed."""
from __future__ import annotations

import ctypes
import math
import subprocess
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

HERE = Path(__file__).resolve().parent
LIB = Path("/tmp/form/libtc.so")
if not LIB.exists() or LIB.stat().st_mtime < (HERE / "c" / "twochamber.c").stat().st_mtime:
    subprocess.check_call(["gcc", "-O2", "-shared", "-fPIC", "-o", str(LIB), str(HERE / "c" / "twochamber.c"), "-lm"])
_lib = ctypes.CDLL(str(LIB))
_D = ctypes.POINTER(ctypes.c_double)
_lib.simulate_tc.argtypes = [ctypes.c_int, _D, ctypes.c_double, ctypes.c_int, ctypes.c_int, _D, _D, ctypes.c_int, _D, _D,
                             ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             ctypes.c_double, ctypes.c_double, _D, ctypes.POINTER(ctypes.c_int)]
_lib.simulate_tc.restype = ctypes.c_int
CCHK = 1e3


def _p(a):
    return a.ctypes.data_as(_D)


U_EPS = 1e-4  # m/s: the check's cracking force is reached over this rate (regularised step)


def _check(crack, cchk):
    if crack > 0:
        return [-1.0, -U_EPS, 0.0], [-crack - cchk, -crack, 0.0]
    return [-1.0, 0.0], [-cchk, 0.0]


def valve_tables(fc_x, fc_f, a, cchk=CCHK, crack_p=0.0, crack_f=0.0):
    fc_x, fc_f = np.asarray(fc_x), np.asarray(fc_f)
    pos = fc_x > 0
    cx, cf = _check(crack_p, cchk)
    fpx = np.concatenate([cx, fc_x[pos]])
    fpf = np.concatenate([cf, fc_f[pos]])
    r = 1.0 - a
    ux = (-r * fc_x[~pos])[::-1]
    uf = (-fc_f[~pos] / r)[::-1]
    cx, cf = _check(crack_f, cchk)
    ffx = np.concatenate([cx, ux])
    fff = np.concatenate([cf, uf])
    return [np.ascontiguousarray(v, float) for v in (fpx, fpf, ffx, fff)]


def simulate(x, dt, prm, sub=4):
    x = np.ascontiguousarray(x, float)
    out = np.empty_like(x)
    fpx, fpf, ffx, fff = valve_tables(prm["fc_x"], prm["fc_f"], prm["a"], prm.get("cchk", CCHK),
                                      prm.get("crack_p", 0.0), prm.get("crack_f", 0.0))
    fails = ctypes.c_int(0)
    rc = _lib.simulate_tc(len(x), _p(x), dt, sub, len(fpx), _p(fpx), _p(fpf), len(ffx), _p(ffx), _p(fff),
                          prm["kR"], prm["kC"], prm["a"], prm["kM"], prm["cM"], prm.get("LR", 0.0),
                          prm.get("LC", 0.0), prm.get("air", 0.0), prm.get("fres", 1e3), prm.get("ffric", 0.0),
                          prm.get("veps", 5e-4), _p(out), ctypes.byref(fails))
    if rc or not np.all(np.isfinite(out)):
        raise FloatingPointError("simulation failed")
    return out, fails.value


def sim_signals(s, prm, sub=4):
    tf, xf, vf, _ = s.fine
    out, _ = simulate(xf, float(tf[1] - tf[0]), prm, sub)
    if prm.get("kgas", 0.0):  # reservoir gas spring on the rod, zero at the test start (the rig tares there)
        out = out + prm["kgas"] * (xf - xf[0])
    if prm.get("ffric_out", 0.0):  # the catalogue's friction element: Ff tanh(v1 / v_eps) at the actuator
        out = out + prm["ffric_out"] * np.tanh(vf / prm.get("veps", 5e-4))
    if prm.get("mass", 0.0):  # rod inertia between the load cell and the oil: F += m x1''
        out = out + prm["mass"] * np.gradient(vf, tf)
    return s.band_limit(out)


NAMES = ["kR", "kC", "a", "kM", "cM"]


OPTION_PARAMS = {"pos": ["LR", "LC"], "crack": ["crack_p", "crack_f"], "air": ["air", "fres"], "mass": ["mass"], "gas": ["kgas"], "friction": ["ffric"], "friction_out": ["ffric_out"]}
OPTION_UNITS = {"LR": "m", "LC": "m", "crack_p": "N", "crack_f": "N", "air": "-", "fres": "N", "mass": "kg", "kgas": "N/m", "ffric": "N", "ffric_out": "N"}
LOG = ("LR", "LC", "fres")
LOG_BOUNDS = {"LR": (0.07, 100.0), "LC": (0.07, 100.0), "fres": (10.0, 1e5)}
HI = {"mass": 400.0}  # scaled upper bounds of the linear extras (default 20 x SCALE)
SCALE = {"air": 1.0, "mass": 1.0, "kgas": 1e3, "ffric": 1e2, "ffric_out": 1e2}


class TCForm:
    """options: 'pos' (chamber stiffness with the piston position: LR, LC [m], log-scaled),
    'crack' (check-valve cracking forces crack_p, crack_f [N], linear >= 0)."""

    def __init__(self, fc_x, options=()):
        self.fc_x = np.asarray(fc_x, float)
        self.nneg = int((self.fc_x < 0).sum())
        self.options = tuple(options)
        self.extra = [n for o in self.options for n in OPTION_PARAMS[o]]

    def from_params(self, prm):
        xs, fs = self.fc_x, np.asarray(prm["fc_f"])
        neg = xs < 0
        inc = np.concatenate([np.diff(np.concatenate([[0], -fs[neg][::-1]])), np.diff(np.concatenate([[0], fs[~neg]]))]) / 1e3
        a = prm["a"]
        ext = [math.log(prm[n]) if n in LOG else prm[n] / SCALE.get(n, 1e2) for n in self.extra]
        return np.concatenate([np.maximum(inc, 0), [math.log(prm["kR"]), math.log(prm["kC"]), math.log(a / (1 - a)),
                                                    math.log(prm["kM"]), math.log(prm["cM"])], ext])

    def to_params(self, z):
        z = np.asarray(z, float)
        n = len(self.fc_x)
        inc = np.abs(z[:n]) * 1e3
        fc_f = np.concatenate([-np.cumsum(inc[:self.nneg])[::-1], np.cumsum(inc[self.nneg:])])
        kR, kC, la, kM, cM = z[n:n + 5]
        out = {"fc_x": self.fc_x, "fc_f": fc_f, "kR": math.exp(kR), "kC": math.exp(kC), "a": 1 / (1 + math.exp(-la)),
               "kM": math.exp(kM), "cM": math.exp(cM)}
        for i, nme in enumerate(self.extra):
            v = z[n + 5 + i]
            out[nme] = math.exp(v) if nme in LOG else max(v, 0.0) * SCALE.get(nme, 1e2)
        return out

    def bounds(self):
        n = len(self.fc_x)
        elo = [math.log(LOG_BOUNDS[e][0]) if e in LOG else 0.0 for e in self.extra]
        ehi = [math.log(LOG_BOUNDS[e][1]) if e in LOG else HI.get(e, 20.0) for e in self.extra]
        lo = np.concatenate([np.zeros(n), [math.log(1e5), math.log(1e5), -4.0, math.log(1e5), math.log(1e1)], elo])
        hi = np.concatenate([np.full(n, np.inf), [math.log(1e10), math.log(1e10), 4.0, math.log(1e11), math.log(1e8)], ehi])
        return lo, hi


def residual(form, z, sigs, sub=4):
    prm = form.to_params(z)
    out = []
    for s in sigs:
        try:
            f = sim_signals(s, prm, sub)
        except FloatingPointError:
            f = np.full(s.force.shape, 1e6)
        out.append((s.force - f)[s.mask])
    return np.concatenate(out)


def rmse(form, z, sigs, sub=4):
    r = residual(form, z, sigs, sub)
    return math.sqrt(float(r @ r) / r.size)


def fit(form, z0, sigs, max_nfev=80, sub=2, fixed_a=None):
    lo, hi = form.bounds()
    z0 = np.clip(z0, lo + 1e-9, hi - 1e-9)
    t0 = time.perf_counter()
    sol = least_squares(lambda z: residual(form, z, sigs, sub), z0, bounds=(lo, hi), method="trf",
                        diff_step=1e-5, x_scale="jac", max_nfev=max_nfev, xtol=1e-10, ftol=1e-10)
    return sol.x, time.perf_counter() - t0, sol
