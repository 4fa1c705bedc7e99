"""A fit output folder of the linear Maxwell model whose covariance is given (no fit), for the vehicle
intervals' test (tests/test_vehicle_propagation.py) and benchmark (benchmarks/vehicle_intervals.py); and the
delta method on the eigenvalue critical speed, their independent reference. SI units.
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np

from damper_fmu.fmu import ensure_fmu
from tuner import strict_json
from tuner.identification.intervals import LocalCovariance, ModelIntervals
from tuner.identification.parametrization import Parametrization
from tuner.vehicle.hunting import eigen_critical_speed

KS, C = 1.0e7, 1.0e5  # N/m, N s/m: critical speed about 380 km/h with the campaign's vehicle
SIGMA_LOG = np.array([0.06, 0.04])  # standard deviations of ln k_s, ln c
RHO = 0.3  # their correlation
#: a representation shift of (ln k_s, ln c): the draws add it as a rank-one term (cov_log + s s^T)
SHIFT_LOG = np.array([0.05, 0.03])


def cov_log(sigma_log=SIGMA_LOG, rho: float = RHO) -> np.ndarray:
    """Covariance of (ln k_s, ln c)."""
    cov = np.diag(np.asarray(sigma_log) ** 2)
    cov[0, 1] = cov[1, 0] = rho * sigma_log[0] * sigma_log[1]
    return cov


def maxwell_folder(folder: Path, sigma_log=SIGMA_LOG, rho: float = RHO, shift_log=None) -> dict:
    """Write into ``folder`` the Maxwell model at (KS, C) as a fit would leave it for the vehicle intervals:
    ``fmu/DamperMaxwell_tuned.fmu`` and ``parameters.json`` with the covariance of (ln k_s, ln c) given, in
    the identification's coordinates (each logarithm scaled by its bound range), and the representation
    shift ``shift_log`` of (ln k_s, ln c) (None: none stored). Returns parameters.json's content."""
    par = Parametrization("maxwell")
    space = par.local_space()
    values = {"k_s": KS, "c": C}
    scale = np.array([math.log(par.bounds[n][1]) - math.log(par.bounds[n][0]) for n in ("k_s", "c")])
    cov = cov_log(sigma_log, rho) / np.outer(scale, scale)
    order = [["k_s", "c"].index(n) for n in space.names]
    local = LocalCovariance(coordinates=list(space.names), u=space.from_params(values), resolved=list(space.names),
                            matrix=cov[np.ix_(order, order)], scheme="improved", force_limit_n=par.force_limit,
                            spring_reference_n_per_m=par.spring_reference,
                            shift=None if shift_log is None else (np.asarray(shift_log) / scale)[order])
    iv = ModelIntervals(model="maxwell", parameters=[], covariance_names=[], covariance=np.zeros((0, 0)),
                        method="block sandwich", blocks=0, block_length_s=1.0, correlation_time_s=1.0, samples=0,
                        residual_rms_n=0.0, local=local)
    (folder / "fmu").mkdir(parents=True, exist_ok=True)
    shutil.copy(ensure_fmu("maxwell"), folder / "fmu" / "DamperMaxwell_tuned.fmu")
    params = {"maxwell": {"values": values, "intervals": iv.to_dict()}}
    (folder / "parameters.json").write_text(strict_json.dumps(params))
    return params


def eigen_gradient(h: float = 0.02) -> np.ndarray:
    """d v_crit / d (ln k_s, ln c) [m/s] at (KS, C): the eigenvalue critical speed by central differences."""
    return np.array([(eigen_critical_speed(KS * math.exp(h * e[0]), C * math.exp(h * e[1]), tol=1e-4)
                      - eigen_critical_speed(KS * math.exp(-h * e[0]), C * math.exp(-h * e[1]), tol=1e-4)) / (2 * h)
                     for e in np.eye(2)])
