"""Parameter sets drawn from a fitted covariance (tuner.identification.parameter_draws).

References, each from the coordinates' definition (tuner.identification.parametrization.LocalSpace), not
from the drawing code:
(a) a log-scaled parameter: log(value) is linear in its coordinate, so var(log k_B) = var(u) x (ln hi - ln lo)^2;
(b) a table ordinate is the sum of the increments from zero outward, each linear in its coordinate: the
    ordinates' covariance is A Sigma A^T with A the cumulative widths;
(c) a coordinate fitted at a bound is drawn as the half-Gaussian on the inside (mean sigma sqrt(2/pi));
(d) a coordinate without finite variance is uniform over its bounds (mean 1/2, variance 1/12);
(e) every draw is a valid model: inside the bounds, the tables monotone (damper_fmu.parameters.check_values);
(f) draws depend on (seed, model, index) alone: the first n of 2n are the same;
(g) the representation shift s_u is drawn as a rank-one term: the draws' covariance in u is Sigma + s_u s_u^T,
    so a parameter linear in its coordinate has the marginal variance (std^2 + s^2) and two shifted ones the
    covariance s_a s_b; checked against the sampling distribution of the estimates (a sample variance of N
    normal draws has relative standard error sqrt(2 / (N - 1)), a sample correlation (1 - rho^2) / sqrt(N)).
"""
import math

import numpy as np
import pytest

from damper_fmu.parameters import check_values, defaults
from tuner import strict_json
from tuner.identification.intervals import LocalCovariance, ModelIntervals
from tuner.identification.parameter_draws import draw_parameter_sets, reflect_into_unit_interval
from tuner.identification.parametrization import Parametrization

N = 4000


def lumped_entry(sigma: dict, at_bound: str | None = None, unresolved=(), corr: tuple | None = None,
                 shift: dict | None = None):
    """A parameters.json entry of the lumped model at its preset, with the local covariance diagonal
    (``sigma``: coordinate -> standard deviation in u; others 1e-6), the coordinate ``at_bound`` moved to
    its upper bound, ``unresolved`` coordinates without finite variance, ``corr`` = (a, b, rho), ``shift``:
    coordinate -> representation shift in u (None: none stored, as a file written before it was)."""
    values = defaults("lumped")
    par = Parametrization("lumped", force_limit=3.0e4, spring_reference=1.5e7,
                          fixed={k: v for k, v in values.items() if k.startswith(("Fc_v", "Fk_x"))})
    space = par.local_space()
    u = space.from_params(values)
    if at_bound:
        u[space.names.index(at_bound)] = 1.0
    values = {**values, **space.to_params(u)}
    resolved = [c for c in space.names if c not in unresolved]
    s = np.array([sigma.get(c, 1e-6) for c in resolved])
    cov = np.diag(s ** 2)
    if corr:
        a, b, rho = resolved.index(corr[0]), resolved.index(corr[1]), corr[2]
        cov[a, b] = cov[b, a] = rho * s[a] * s[b]
    local = LocalCovariance(coordinates=list(space.names), u=u, resolved=resolved, matrix=cov, scheme="improved",
                            force_limit_n=3.0e4, spring_reference_n_per_m=1.5e7,
                            shift=None if shift is None else np.array([shift.get(c, 0.0) for c in space.names]))
    iv = ModelIntervals(model="lumped", parameters=[], covariance_names=[], covariance=np.zeros((0, 0)),
                        method="block sandwich", blocks=0, block_length_s=1.0, correlation_time_s=1.0, samples=0,
                        residual_rms_n=0.0, local=local)
    entry = {"values": values, "intervals": strict_json.loads(strict_json.dumps(iv.to_dict()))}
    return entry, par, space


def test_a_log_scaled_parameter_is_lognormal_with_the_coordinate_variance():
    entry, par, _ = lumped_entry({"k_B": 0.02})
    draws = draw_parameter_sets("lumped", entry, N, seed=1)
    lo, hi = par.bounds["k_B"]
    logs = np.log(draws.matrix()[:, draws.names.index("k_B")])
    expected = 0.02 * (math.log(hi) - math.log(lo))
    assert np.std(logs) == pytest.approx(expected, rel=0.05)
    assert np.mean(logs) == pytest.approx(math.log(entry["values"]["k_B"]), abs=4 * expected / math.sqrt(N))


def test_b_table_ordinates_sum_the_increments():
    sig = {"Fc_08": 0.01, "Fc_09": 0.02, "Fc_10": 0.015}
    entry, par, space = lumped_entry(sig, corr=("Fc_08", "Fc_09", 0.5))
    draws = draw_parameter_sets("lumped", entry, N, seed=2)
    names = ["Fc_08", "Fc_09", "Fc_10"]  # the first three pieces on the positive side, outward from zero
    x = [0.0] + [entry["values"][n.replace("Fc_", "Fc_v")] for n in names]
    lo, hi = par._fc_slopes()
    width = [(math.exp(hi) - math.exp(lo)) * (x[k + 1] - x[k]) for k in range(3)]  # increment per unit u
    sigma_u = np.diag([sig[n] ** 2 for n in names])
    sigma_u[0, 1] = sigma_u[1, 0] = 0.5 * sig["Fc_08"] * sig["Fc_09"]
    A = np.tril(np.ones((3, 3))) * np.array(width)[None, :]
    expected = A @ sigma_u @ A.T
    got = np.cov(draws.matrix()[:, [draws.names.index(n) for n in names]].T)
    assert np.allclose(np.sqrt(np.diag(got)), np.sqrt(np.diag(expected)), rtol=0.06)
    corr = lambda c: c[0, 2] / math.sqrt(c[0, 0] * c[2, 2])  # noqa: E731
    assert corr(got) == pytest.approx(corr(expected), abs=0.05)


def test_c_a_coordinate_at_its_bound_is_drawn_half_gaussian_inside():
    entry, par, space = lumped_entry({"M_O": 0.05}, at_bound="M_O")
    draws = draw_parameter_sets("lumped", entry, N, seed=3)
    m = draws.matrix()[:, draws.names.index("M_O")]
    lo, hi = par.bounds["M_O"]
    assert np.all(m <= hi) and np.all(m >= lo)
    offset = (hi - m) / (hi - lo)  # distance from the bound in u
    assert np.mean(offset) == pytest.approx(0.05 * math.sqrt(2 / math.pi), rel=0.05)
    assert np.std(offset) == pytest.approx(0.05 * math.sqrt(1 - 2 / math.pi), rel=0.06)
    assert draws.reflected["M_O"] == pytest.approx(0.5, abs=0.03)


def test_d_coordinates_without_finite_variance_are_uniform_within_the_bounds():
    entry, par, _ = lumped_entry({}, unresolved=("M_C", "c_B"))
    draws = draw_parameter_sets("lumped", entry, N, seed=4)
    assert draws.uniform == ["M_C", "c_B"] or set(draws.uniform) == {"M_C", "c_B"}
    lo, hi = par.bounds["M_C"]
    u = (draws.matrix()[:, draws.names.index("M_C")] - lo) / (hi - lo)
    assert np.mean(u) == pytest.approx(0.5, abs=0.02)
    assert np.var(u) == pytest.approx(1 / 12, rel=0.06)
    clo, chi = par.bounds["c_B"]  # log-scaled: log-uniform
    lu = (np.log(draws.matrix()[:, draws.names.index("c_B")]) - math.log(clo)) / (math.log(chi) - math.log(clo))
    assert np.mean(lu) == pytest.approx(0.5, abs=0.02)
    assert "M_C" in draws.describe() and "uniformly" in draws.describe()


def test_e_every_draw_is_a_valid_model_even_with_wide_variances():
    sig = {c: 0.4 for c in ("Fc_01", "Fc_07", "Fc_08", "Fc_14", "Fk_01", "Fk_10", "M_P", "k_B")}
    entry, _, _ = lumped_entry(sig, at_bound="Fc_14")
    draws = draw_parameter_sets("lumped", entry, 200, seed=5)
    fixed = {k: v for k, v in entry["values"].items() if k.startswith(("Fc_v", "Fk_x"))}
    for s in draws.sets:
        check_values("lumped", {**fixed, **s}, bounds=True)


def test_f_draws_depend_on_seed_model_and_index_alone():
    entry, _, _ = lumped_entry({"k_B": 0.02, "M_P": 0.1}, unresolved=("M_C",))
    a = draw_parameter_sets("lumped", entry, 5, seed=7).matrix()
    b = draw_parameter_sets("lumped", entry, 10, seed=7).matrix()
    c = draw_parameter_sets("lumped", entry, 5, seed=8).matrix()
    assert np.array_equal(a, b[:5])
    assert not np.allclose(a, c)


def test_g_the_representation_shift_is_drawn_as_a_rank_one_term():
    sig, shift = {"M_P": 0.01, "M_O": 0.015, "M_C": 0.01}, {"M_P": 0.02, "M_O": -0.01}
    entry, par, _ = lumped_entry(sig, shift=shift)
    draws = draw_parameter_sets("lumped", entry, N, seed=6)
    m = draws.matrix()
    width = {n: par.bounds[n][1] - par.bounds[n][0] for n in sig}  # the masses are linear in their coordinate
    col = {n: m[:, draws.names.index(n)] for n in sig}
    var = {n: (sig[n] ** 2 + shift.get(n, 0.0) ** 2) * width[n] ** 2 for n in sig}  # std^2 + s^2
    tol = 4.0 * math.sqrt(2.0 / (N - 1))  # four standard errors of a sample variance, relative
    for n in sig:
        assert np.var(col[n], ddof=1) / var[n] == pytest.approx(1.0, abs=tol), n
    rho = shift["M_P"] * shift["M_O"] * width["M_P"] * width["M_O"] / math.sqrt(var["M_P"] * var["M_O"])
    got = np.corrcoef(col["M_P"], col["M_O"])[0, 1]
    assert got == pytest.approx(rho, abs=4.0 * (1 - rho ** 2) / math.sqrt(N))
    assert draws.shift and "with the representation shift" in draws.describe()
    # a file written before the shift was stored: the statistical covariance alone, said
    old = {**entry, "intervals": {**entry["intervals"], "local_covariance": {
        k: v for k, v in entry["intervals"]["local_covariance"].items() if k != "shift"}}}
    n_old = N // 4  # variance sigma^2 against the 5 sigma^2 with the shift: fewer draws tell them apart
    stat = draw_parameter_sets("lumped", old, n_old, seed=6)
    m_p = stat.matrix()[:, stat.names.index("M_P")]
    tol_old = 4.0 * math.sqrt(2.0 / (n_old - 1))
    assert np.var(m_p, ddof=1) / (sig["M_P"] * width["M_P"]) ** 2 == pytest.approx(1.0, abs=tol_old)
    assert not stat.shift and "without the representation shift" in stat.describe()


def test_reflection_and_bad_input():
    assert np.allclose(reflect_into_unit_interval([-0.2, 0.3, 1.2, 2.3, -1.5]), [0.2, 0.3, 0.8, 0.3, 0.5])
    entry, _, _ = lumped_entry({})
    with pytest.raises(ValueError, match="positive integer"):
        draw_parameter_sets("lumped", entry, 0)
    with pytest.raises(ValueError, match="lumped: no parameter intervals"):
        draw_parameter_sets("lumped", {"values": entry["values"], "intervals": None,
                                       "intervals_note": "not computed: x"}, 3)
    old = {**entry, "intervals": {**entry["intervals"], "local_covariance": None}}
    with pytest.raises(ValueError, match="refit"):
        draw_parameter_sets("lumped", old, 3)
