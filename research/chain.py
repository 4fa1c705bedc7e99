"""Python side of the massless chain prototype (research/c/chain.c): model forms for issue 12.

Model = silent blocks (kM, cM: both blocks in series) -- damping table Fc,O(z') -- elastic table
Fk,O(e), plus an optional extra branch (kind: 'sls' linear Maxwell k2/c2, 'jenkins' elasto-plastic
k2/Fy+/Fy-, 'maxwell_clip' Maxwell with a force limit k2/c2/Fy), attached in parallel to the elastic
element ('inner') or to elastic + damping elements ('outer'). Masses are left out (the twin-tube
attribution shows they do not matter: light_masses changes the base RMSE by 0.1 N).
Compared band-limited with the data as tuner.identification.engine does (fine grid at 1 ms, low-pass back)."""
from __future__ import annotations

import ctypes
import math
import subprocess
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

HERE = Path(__file__).resolve().parent
LIB = Path("/tmp/form/libchain.so")
if not LIB.exists() or LIB.stat().st_mtime < (HERE / "c" / "chain.c").stat().st_mtime:
    subprocess.check_call(["gcc", "-O2", "-shared", "-fPIC", "-o", str(LIB), str(HERE / "c" / "chain.c"), "-lm"])
_lib = ctypes.CDLL(str(LIB))
_D = ctypes.POINTER(ctypes.c_double)
_lib.simulate.argtypes = ([ctypes.c_int, _D, ctypes.c_double, ctypes.c_int, ctypes.c_int, _D, _D, ctypes.c_int, _D, _D,
                           ctypes.c_double, ctypes.c_double, ctypes.c_int, ctypes.c_int] + [ctypes.c_double] * 6 + [_D])
_lib.simulate.restype = ctypes.c_int
KINDS = {"none": 0, "pos": 0, "gas": 0, "pos_gas": 0, "sls": 1, "jenkins": 2, "maxwell_clip": 3}
EXTRA = {"none": [], "pos": ["LR", "LC"], "gas": ["kgas"], "pos_gas": ["LR", "LC", "kgas"], "sls": ["k2", "c2"], "jenkins": ["k2", "fy_pos", "fy_neg"], "maxwell_clip": ["k2", "c2", "fy"],
         "jenkins_sym": ["k2", "fy"]}
UNITS = {"kgas": "N/m", "LR": "m", "LC": "m", "k2": "N/m", "c2": "N s/m", "fy": "N", "fy_pos": "N", "fy_neg": "N"}


def _p(a):
    return a.ctypes.data_as(_D)


def simulate(x, dt, prm, kind="none", attach="inner", sub=5):
    x = np.ascontiguousarray(x, float)
    out = np.empty_like(x)
    fcx = np.ascontiguousarray(np.insert(prm["fc_x"], np.searchsorted(prm["fc_x"], 0.0), 0.0))
    fcf = np.ascontiguousarray(np.insert(prm["fc_f"], np.searchsorted(prm["fc_x"], 0.0), 0.0))
    fkx = np.ascontiguousarray(np.insert(prm["fk_x"], np.searchsorted(prm["fk_x"], 0.0), 0.0))
    fkf = np.ascontiguousarray(np.insert(prm["fk_f"], np.searchsorted(prm["fk_x"], 0.0), 0.0))
    k = "jenkins" if kind == "jenkins_sym" else kind
    fyp = prm.get("fy_pos", prm.get("fy", 0.0))
    fyn = prm.get("fy_neg", prm.get("fy", 0.0))
    rc = _lib.simulate(len(x), _p(x), dt, sub, len(fcx), _p(fcx), _p(fcf), len(fkx), _p(fkx), _p(fkf),
                       prm["kM"], prm["cM"], KINDS[k], 0 if attach == "inner" else 1, prm.get("k2", 0.0),
                       prm.get("c2", 0.0), fyp, fyn, prm.get("LR", 0.0), prm.get("LC", 0.0), _p(out))
    if rc:
        raise FloatingPointError("simulation failed")
    return out


def sim_signals(s, prm, kind, attach, sub=5):
    tf, xf, vf, _ = s.fine
    dt = float(tf[1] - tf[0])
    out = simulate(xf, dt, prm, kind, attach, sub)
    if prm.get("kgas", 0.0):  # gas spring on the rod, zero at the test start
        out = out + prm["kgas"] * (xf - xf[0])
    return s.band_limit(out)


class Form:
    """Parametrization of the chain: positive increments of the tables (kN), logs of the rest."""

    def __init__(self, axes: dict, kind="none", attach="inner"):
        self.fc_x = np.array([axes[f"Fc_v{i:02d}"] for i in range(1, 15)])
        self.fk_x = np.array([axes[f"Fk_x{i:02d}"] for i in range(1, 11)])
        self.kind, self.attach = kind, attach
        self.extra = EXTRA[kind]

    @staticmethod
    def _incr(xs, fs):
        """table ordinates -> |increments| outward from 0 on each side [kN]"""
        neg = xs < 0
        fn = fs[neg][::-1]; fp = fs[~neg]
        return np.concatenate([np.diff(np.concatenate([[0], -fn])), np.diff(np.concatenate([[0], fp]))]) / 1e3, neg.sum()

    @staticmethod
    def _ords(inc, nneg):
        inc = np.abs(inc) * 1e3
        fn = -np.cumsum(inc[:nneg])[::-1]
        fp = np.cumsum(inc[nneg:])
        return np.concatenate([fn, fp])

    def from_params(self, prm: dict) -> np.ndarray:
        ic, _ = self._incr(self.fc_x, np.asarray(prm["fc_f"]))
        ik, _ = self._incr(self.fk_x, np.asarray(prm["fk_f"]))
        rest = [math.log(prm["kM"]), math.log(prm["cM"])] + [math.log(prm[n]) for n in self.extra]
        return np.concatenate([ic, ik, rest])

    def to_params(self, z) -> dict:
        z = np.asarray(z, float)
        nc, nk = len(self.fc_x), len(self.fk_x)
        prm = {"fc_x": self.fc_x, "fk_x": self.fk_x,
               "fc_f": self._ords(z[:nc], int((self.fc_x < 0).sum())),
               "fk_f": self._ords(z[nc:nc + nk], int((self.fk_x < 0).sum())),
               "kM": math.exp(z[nc + nk]), "cM": math.exp(z[nc + nk + 1])}
        for i, n in enumerate(self.extra):
            prm[n] = math.exp(z[nc + nk + 2 + i])
        return prm

    def bounds(self):
        nc, nk = len(self.fc_x), len(self.fk_x)
        lo = np.concatenate([np.zeros(nc), np.full(nk, 1e-3), [math.log(1e5), math.log(1e2)], np.full(len(self.extra), -np.inf)])
        hi = np.concatenate([np.full(nc + nk, np.inf), [math.log(1e10), math.log(1e8)], np.full(len(self.extra), np.inf)])
        return lo, hi


def from_lumped(base: dict) -> dict:
    return {"fc_x": np.array([base[f"Fc_v{i:02d}"] for i in range(1, 15)]),
            "fc_f": np.array([base[f"Fc_{i:02d}"] for i in range(1, 15)]),
            "fk_x": np.array([base[f"Fk_x{i:02d}"] for i in range(1, 11)]),
            "fk_f": np.array([base[f"Fk_{i:02d}"] for i in range(1, 11)]),
            "kM": base["k_B"] / 2, "cM": base["c_B"] / 2}


def residual(form: Form, z, sigs, sub=5):
    prm = form.to_params(z)
    out = []
    for s in sigs:
        try:
            f = sim_signals(s, prm, form.kind, form.attach, sub)
        except FloatingPointError:
            f = np.full(s.force.shape, 1e6)
        out.append((s.force - f)[s.mask])
    return np.concatenate(out)


def rmse(form, z, sigs, sub=5):
    r = residual(form, z, sigs, sub)
    return math.sqrt(float(r @ r) / r.size)


def fit(form: Form, z0, sigs, max_nfev=400, sub=5, log=print):
    lo, hi = form.bounds()
    z0 = np.clip(z0, lo + 1e-12, hi - 1e-12)
    t0 = time.perf_counter()
    sol = least_squares(lambda z: residual(form, z, sigs, sub), z0, bounds=(lo, hi), method="trf",
                        diff_step=1e-5, x_scale="jac", max_nfev=max_nfev, xtol=1e-10, ftol=1e-10)
    return sol.x, time.perf_counter() - t0, sol
