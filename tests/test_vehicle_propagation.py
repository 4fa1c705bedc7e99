"""The identification's uncertainty carried to the vehicle (tuner.vehicle.propagation), against independent
references:

(a) the linear Maxwell FMU with a given covariance of (k_s, c) and representation shift s: every draw's
    time-domain critical speed (kick runs through the co-simulation) against the eigenvalue critical speed
    of campaign.vehicle's linear model at the same parameters; the spread of the draws against the delta
    method, the eigenvalue critical speed finite-differenced in log k_s and log c, on the same draws (common
    random numbers: no Monte-Carlo error in that comparison); the interval against the delta method's on
    the covariance plus s s^T (the parameters' intervals hold the shift), within the stated Monte-Carlo
    error;
(b) the interval statistics: over many repetitions, the ends of the normal-theory interval and of the
    empirical quantiles scatter as the stated Monte-Carlo error says, around the true 2.5 % / 97.5 % points;
(c) the robust search finds the eigenvalue critical speed (linear FMU) from a guess far off.
"""
import math
from argparse import Namespace

import numpy as np
import pytest

from damper_fmu.fmu import ensure_fmu
from tuner.cli.options import vehicle_scheduler
from tuner.cli.summary import vehicle_interval_summary
from tuner.identification.parameter_draws import draw_parameter_sets
from tuner.metrics import Z95
from tuner.results.vehicle_report import intervals_html
from tuner.vehicle.cosim import VehicleCosim
from tuner.vehicle.hunting import NearSearch, critical_speed_near, eigen_critical_speed
from tuner.vehicle.propagation import PropagationSettings, figure_interval, propagate
from vehicle_interval_cases import KS, SHIFT_LOG, C, cov_log, eigen_gradient, maxwell_folder

DRAWS = 12


def test_a_maxwell_critical_speed_interval_agrees_with_the_delta_method_on_eigenvalues(tmp_path):
    folder, params = tmp_path, maxwell_folder(tmp_path, shift_log=SHIFT_LOG)
    settings = PropagationSettings(draws=DRAWS, batch=DRAWS, v_min_ms=250 / 3.6, v_max_ms=550 / 3.6,
                                   half_width_ms=20 / 3.6, seed=3)
    data = propagate(folder, settings, log=lambda m: None)
    res = data["results"]["DamperMaxwell_tuned"]
    cs = res["critical_speed"]
    v0 = eigen_critical_speed(KS, C, tol=1e-3)
    assert cs["nominal"] == pytest.approx(v0, rel=2e-3)
    # every draw against the eigenvalues at its own parameters
    draws = draw_parameter_sets("maxwell", params["maxwell"], DRAWS, settings.seed)
    td = np.array([o["critical_speed"] for o in sorted(res["outcomes"], key=lambda o: o["index"]) if o["index"] >= 0])
    eig = np.array([eigen_critical_speed(p["k_s"], p["c"], tol=1e-3) for p in draws.sets])
    assert np.max(np.abs(td - eig)) < 2e-3 * v0, np.c_[td, eig] * 3.6
    # the delta method: gradient of the eigenvalue critical speed in (ln k_s, ln c) by central differences
    grad = eigen_gradient()
    sd_delta = math.sqrt(grad @ (cov_log() + np.outer(SHIFT_LOG, SHIFT_LOG)) @ grad)
    assert sd_delta > 5 / 3.6  # a spread worth testing: several km/h
    # same draws, linearised: no Monte-Carlo error between the two
    dlog = np.log(draws.matrix() / np.array([KS, C]))
    linear = v0 + dlog @ grad
    assert np.std(td, ddof=1) == pytest.approx(np.std(linear, ddof=1), rel=0.05)
    # the interval against the delta method's, within the stated Monte-Carlo error
    assert cs["method"] == "normal" and cs["draws"] == DRAWS and cs["mc_error"] > 0
    assert abs(cs["low"] - (v0 - Z95 * sd_delta)) < 3 * cs["mc_error"] + 1e-3 * v0
    assert abs(cs["high"] - (v0 + Z95 * sd_delta)) < 3 * cs["mc_error"] + 1e-3 * v0
    # the curve's peak force: a damper with higher c and k_s pushes harder; the interval holds the nominal
    pf = res["peak_curve_force"]
    assert pf["low"] < pf["nominal"] < pf["high"]
    force = np.array([o["peak_curve_force"] for o in sorted(res["outcomes"], key=lambda o: o["index"])
                      if o["index"] >= 0])
    assert np.corrcoef(force, dlog[:, 1])[0, 1] > 0.5
    assert "km/h (95 %:" in res["critical_speed_text"]
    # what the report and summary.json say is what intervals.json holds, in km/h
    assert res["critical_speed_text"] in intervals_html(folder / "vehicle")
    summary = vehicle_interval_summary(folder)["DamperMaxwell_tuned"]
    assert summary["critical_speed_kmh"]["low"] == pytest.approx(cs["low"] * 3.6)
    assert summary["text"].startswith("critical speed ") and "with the linear Maxwell FMU" in summary["text"]


def test_b_stated_monte_carlo_error_matches_the_scatter_of_the_ends():
    rng = np.random.default_rng(0)
    true = (-Z95, Z95)
    for n, method in ((24, "normal"), (400, "percentile")):
        ends, errors = [], []
        for _ in range(600):
            fi = figure_interval(rng.standard_normal(n), 0.0, "x", "1")
            assert fi.method == method
            ends.append((fi.low, fi.high))
            errors.append(fi.mc_error)
        ends = np.array(ends)
        scatter = np.std(ends, axis=0)
        assert np.all(np.abs(np.mean(ends, axis=0) - true) < 0.15)
        assert np.median(errors) == pytest.approx(np.mean(scatter), rel=0.3), (n, np.median(errors), scatter)


def test_b_censored_draws_are_said_and_use_the_quantiles():
    fi = figure_interval([700.0, 710.0, 720.0, math.inf, 705.0, 715.0], 710.0, "critical speed", "m/s", top=800.0)
    assert fi.censored_high == 1 and fi.method == "percentile" and fi.high <= 800.0
    with pytest.raises(ValueError, match="at least 2 draws"):
        figure_interval([1.0], 1.0, "x", "1", failed=3)


def test_c_robust_search_finds_the_eigenvalue_critical_speed_from_far():
    v0 = eigen_critical_speed(KS, C, tol=1e-3)
    with VehicleCosim(ensure_fmu("maxwell"), fmu_parameters={"k_s": KS, "c": C}) as co:
        res = critical_speed_near(co, v0 + 90 / 3.6, search=NearSearch(half_width=15 / 3.6, v_min=150 / 3.6,
                                                                       v_max=700 / 3.6))
    assert res.speed == pytest.approx(v0, rel=2e-3)


def test_bad_settings_and_folders_are_named(tmp_path):
    with pytest.raises(ValueError, match="--vehicle-draws"):
        propagate(tmp_path, PropagationSettings(draws=1))
    with pytest.raises(FileNotFoundError, match="parameters.json"):
        propagate(tmp_path, PropagationSettings())


def test_the_command_line_options_are_checked_and_mapped():
    assert vehicle_scheduler(Namespace(vehicle_draws=24, vehicle_scheduler=None, workers=2)) == "pool:2"
    assert vehicle_scheduler(Namespace(vehicle_draws=24, vehicle_scheduler=None, workers=0)) is None
    assert vehicle_scheduler(Namespace(vehicle_draws=24, vehicle_scheduler="here", workers=2)) is None
    assert vehicle_scheduler(Namespace(vehicle_draws=24, vehicle_scheduler="local:2", workers=2)) == "local:2"
    with pytest.raises(ValueError, match="--vehicle-scheduler"):
        vehicle_scheduler(Namespace(vehicle_draws=24, vehicle_scheduler="pool:x", workers=2))
    with pytest.raises(ValueError, match="--vehicle-draws"):
        vehicle_scheduler(Namespace(vehicle_draws=1, vehicle_scheduler=None, workers=2))


def test_only_the_models_asked_for_are_drawn(tmp_path):
    """``PropagationSettings.models``: a folder's FMU of another model gets no plan (and no simulation)."""
    folder = tmp_path
    maxwell_folder(folder, shift_log=SHIFT_LOG)
    data = propagate(folder, PropagationSettings(draws=2, batch=2, models=("lumped",)), log=lambda m: None)
    assert data["results"] == {} and data["errors"] == {}
