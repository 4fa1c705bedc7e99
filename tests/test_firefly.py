"""Firefly algorithm (paper section 2.3): convergence on analytic functions with the paper's
budget (P = 20, 150 iterations), move rule against a plain-loop reading of eqs. 6-8,
determinism, checkpoint/resume, evaluation accounting, failure handling, stopping rule.

Convergence tolerances are "optimum region" definitions fixed before running, stated per
case. The literal algorithm is a weak optimiser beyond a few dimensions (rho = 0.9^(k-1)
kills exploration after ~40 iterations); on 5-D Rosenbrock it does not reach (1, ..., 1)
within the budget, so there the test only claims it beats uniform random search with
the same number of evaluations (in the median over seeds).
"""
import json

import numpy as np
import pytest

from tuner.identification.firefly import FireflyOptions, FireflyState, move_population, run

SEEDS = range(5)


def _fit(f):
    """Fitness 1 / (f + small) for a batch objective f(X) >= 0 on scaled X."""
    return lambda X: 1.0 / (f(X) + 1e-12)


def sphere(c):
    c = np.asarray(c, dtype=float)
    return lambda X: ((X - c) ** 2).sum(axis=1)


def rosenbrock(X):                       # z in [-2, 2]^d, optimum z = 1 -> x = 0.75
    z = -2.0 + 4.0 * X
    return (100.0 * (z[:, 1:] - z[:, :-1] ** 2) ** 2 + (1.0 - z[:, :-1]) ** 2).sum(axis=1)


def rastrigin(X):                        # z in [-5.12, 5.12]^d, optimum z = 0 -> x = 0.5
    z = -5.12 + 10.24 * X
    return 10.0 * X.shape[1] + (z ** 2 - 10.0 * np.cos(2.0 * np.pi * z)).sum(axis=1)


# ---------------------------------------------------------------- convergence

C5 = np.array([0.8, 0.15, 0.67, 0.08, 0.76])


@pytest.mark.parametrize("name, f, x_opt, tol", [
    # 2-D: within 1 % of each range; 5-D: within 10 % of each range
    ("sphere 5-D", sphere(np.full(5, 0.5)), np.full(5, 0.5), 0.10),
    ("shifted sphere 2-D", sphere(C5[:2]), C5[:2], 0.01),
    ("shifted sphere 5-D", sphere(C5), C5, 0.10),
    # Rosenbrock 2-D: within 5 % of the range (|z - 1| < 0.2) along the flat valley
    ("Rosenbrock 2-D", rosenbrock, np.full(2, 0.75), 0.05),
    # Rastrigin 2-D: inside the global basin, |z| < 0.5 (local minima sit at integer z)
    ("Rastrigin 2-D", rastrigin, np.full(2, 0.5), 0.5 / 10.24),
])
def test_finds_optimum_region(name, f, x_opt, tol):
    for seed in SEEDS:
        r = run(_fit(f), x_opt.size, seed=seed)
        dist = np.abs(r.x_best - x_opt).max()
        assert dist < tol, f"{name}, seed {seed}: |x - x*|_inf = {dist:.3g} >= {tol:.3g}"


def test_rosenbrock_3d_reaches_valley_near_optimum():
    # f < 1, half the value at the box centre z = 0 (f = 2) where the random term pulls
    for seed in SEEDS:
        r = run(_fit(rosenbrock), 3, seed=seed)
        assert rosenbrock(r.x_best[None])[0] < 1.0, f"seed {seed}"


@pytest.mark.parametrize("name, f, d, every_seed", [
    ("shifted sphere 5-D", sphere(C5), 5, True),
    ("Rosenbrock 3-D", rosenbrock, 3, True),
    # 5-D Rosenbrock: over 30 seeds the median FA/random ratio of best f is 0.16 but one
    # seed lost (ratio 1.18), so only the median over the seeds is claimed
    ("Rosenbrock 5-D", rosenbrock, 5, False),
])
def test_beats_random_search_with_same_budget(name, f, d, every_seed):
    ratios = []
    for seed in SEEDS:
        r = run(_fit(f), d, seed=seed, options=FireflyOptions(stop_tol=None))
        random_best = f(np.random.default_rng(10_000 + seed).random((r.evaluations, d))).min()
        ratios.append(f(r.x_best[None])[0] / random_best)
    if every_seed:
        assert max(ratios) < 1.0, f"{name}: best-f ratio FA / random search {ratios}"
    else:
        assert np.median(ratios) < 1.0, f"{name}: best-f ratio FA / random search {ratios}"


# ---------------------------------------------------------------- move rule (eqs. 6-8)

def _reference_attraction(X, G, g0, eps, normalise):
    """Plain-loop eq. 6 attraction part, clipped to the box (the documented reading)."""
    P, d = X.shape
    out = X.copy()
    for i in range(P):
        brighter = [j for j in range(P) if G[j] > G[i]]
        step = np.zeros(d)
        for j in brighter:
            dij = np.sqrt(sum((X[j, p] - X[i, p]) ** 2 for p in range(d)))       # eq. 7
            g = g0 / len(brighter) if normalise else g0
            step += g / (1.0 + eps * dij ** 2) * (X[j] - X[i])
        out[i] = np.clip(X[i] + step, 0.0, 1.0)
    return out


@pytest.mark.parametrize("normalise, g0", [(True, 2.0), (True, 1.0), (False, 1.0)])
def test_move_without_random_term_matches_loop_reference(normalise, g0):
    rng = np.random.default_rng(5)
    X = rng.random((7, 4))
    G = rng.random(7)
    opts = FireflyOptions(population=7, g0=g0, normalise_g0=normalise)
    new = move_population(X, G, 0.0, opts, np.random.default_rng(0))
    np.testing.assert_allclose(new, _reference_attraction(X, G, g0, 0.8, normalise), rtol=0, atol=1e-14)
    # the brightest has no brighter firefly and stays exactly
    np.testing.assert_array_equal(new[np.argmax(G)], X[np.argmax(G)])


def test_normalised_g0_1_is_convex_combination_of_brighter_ones():
    rng = np.random.default_rng(8)
    X = rng.random((20, 3))
    G = rng.random(20)
    new = move_population(X, G, 0.0, FireflyOptions(g0=1.0), rng)
    for i in range(20):
        pts = X[G >= G[i]]
        assert np.all(new[i] >= pts.min(axis=0) - 1e-15) and np.all(new[i] <= pts.max(axis=0) + 1e-15)


def test_random_term_is_uniform_within_eq8_bounds():
    # two fireflies; the dimmer one's attraction point a is known from the loop reference,
    # eq. 8 gives x_new = a + rho R with R ~ U[-a, 1 - a]: range [a (1 - rho), a + rho (1 - a)],
    # mean a + rho (0.5 - a), standard deviation rho / sqrt(12)
    X = np.array([[0.2, 0.9, 0.5], [0.6, 0.3, 0.5]])
    G = np.array([1.0, 2.0])
    a = _reference_attraction(X, G, 2.0, 0.8, True)[0]
    rho = 0.4
    rng = np.random.default_rng(21)
    draws = np.array([move_population(X, G, rho, FireflyOptions(population=2), rng)[0] for _ in range(4000)])
    assert np.all(draws >= a * (1 - rho) - 1e-15) and np.all(draws <= a + rho * (1 - a) + 1e-15)
    se = rho / np.sqrt(12 * len(draws))
    np.testing.assert_allclose(draws.mean(axis=0), a + rho * (0.5 - a), atol=5 * se)
    np.testing.assert_allclose(draws.std(axis=0), rho / np.sqrt(12), rtol=0.05)


def test_moves_stay_in_box_and_brightest_stays():
    corner = np.zeros(6)
    corner[:3] = 1.0

    def evaluate(X):
        assert np.all(X >= 0.0) and np.all(X <= 1.0)
        return _fit(sphere(corner))(X)

    for opts in (FireflyOptions(), FireflyOptions(normalise_g0=False, g0=1.0), FireflyOptions(g0=5.0)):
        gens = []
        run(evaluate, 6, options=opts, seed=1, callback=lambda s: gens.append((s.population.copy(), s.fitness.copy())))
        for (Xa, Ga), (Xb, _) in zip(gens[:-1], gens[1:]):
            best = np.flatnonzero(Ga == Ga.max())
            np.testing.assert_array_equal(Xb[best], Xa[best])


def test_brightest_moves_option_moves_everyone():
    gens = []
    run(_fit(sphere([0.3, 0.3])), 2, options=FireflyOptions(brightest_moves=True, max_iterations=3), seed=0,
        callback=lambda s: gens.append(s.population.copy()))
    assert np.all(np.any(gens[1] != gens[0], axis=1))


# ---------------------------------------------------------------- bookkeeping

class Counting:
    def __init__(self, f):
        self.f, self.calls, self.rows, self.values, self.points = f, 0, 0, [], []

    def __call__(self, X):
        self.calls += 1
        self.rows += X.shape[0]
        g = self.f(X)
        self.values.append(np.asarray(g, dtype=float).copy())
        self.points.append(X.copy())
        return g


def test_evaluation_count_and_history_exact():
    obj = Counting(_fit(rosenbrock))
    r = run(obj, 3, options=FireflyOptions(max_iterations=37, stop_tol=None), seed=4)
    assert r.iterations == 37 and r.stop_reason == "max_iterations"
    assert obj.calls == 38                                  # one batch per generation
    assert obj.rows == r.evaluations == 20 + 20 * 37
    assert r.state.history_evaluations == [20 * (t + 1) for t in range(38)]
    assert len(r.state.history_mean) == 38
    np.testing.assert_allclose(r.state.history_mean, [v.mean() for v in obj.values], rtol=1e-15)


def test_max_evaluations_budget():
    obj = Counting(_fit(rosenbrock))
    r = run(obj, 2, seed=0, max_evaluations=250)
    assert r.stop_reason == "max_evaluations" and r.evaluations == obj.rows == 240
    with pytest.raises(ValueError, match="below one generation"):
        run(obj, 2, seed=0, max_evaluations=19)


def test_best_ever_is_max_of_everything_evaluated_and_monotone():
    obj = Counting(_fit(rastrigin))
    r = run(obj, 2, seed=7)
    allv = np.concatenate(obj.values)
    allx = np.concatenate(obj.points)
    assert r.fitness_best == allv.max()
    np.testing.assert_array_equal(r.x_best, allx[np.argmax(allv)])
    hb = np.asarray(r.state.history_best)
    assert np.all(np.diff(hb) >= 0)
    np.testing.assert_array_equal(hb, np.maximum.accumulate([v.max() for v in obj.values]))


def test_initial_population_seeded_individual():
    opt = C5[:2]
    r = run(_fit(sphere(opt)), 2, seed=0, initial=opt[None, :], options=FireflyOptions(max_iterations=5))
    np.testing.assert_array_equal(r.x_best, opt)
    assert r.state.history_best[0] == pytest.approx(1e12)
    with pytest.raises(ValueError, match="within"):
        run(_fit(sphere(opt)), 2, seed=0, initial=[[1.2, 0.5]])
    with pytest.raises(ValueError, match="shape"):
        run(_fit(sphere(opt)), 2, seed=0, initial=np.zeros((1, 3)))
    with pytest.raises(ValueError, match="more than population"):
        run(_fit(sphere(opt)), 2, seed=0, initial=np.zeros((21, 2)))


# ---------------------------------------------------------------- failures and stopping

def test_nan_and_inf_fitness_are_worst():
    def evaluate(X):
        g = _fit(sphere([0.4, 0.4]))(X)
        g[X[:, 0] > 0.6] = np.nan                 # failed simulations
        g[X[:, 1] > 0.7] = np.inf
        return g

    r = run(evaluate, 2, seed=3)
    assert np.isfinite(r.fitness_best) and r.x_best[0] <= 0.6 and r.x_best[1] <= 0.7
    assert np.all(np.isfinite(r.state.history_mean))
    assert np.abs(r.x_best - 0.4).max() < 0.01


def test_bad_objective_output_rejected():
    with pytest.raises(ValueError, match="shape"):
        run(lambda X: np.ones(3), 2, seed=0)
    with pytest.raises(ValueError, match=">= 0"):
        run(lambda X: -np.ones(X.shape[0]), 2, seed=0)
    with pytest.raises(ValueError, match="d must"):
        run(lambda X: np.ones(X.shape[0]), 0, seed=0)
    with pytest.raises(ValueError, match="rho0"):
        FireflyOptions(rho0=1.5)
    with pytest.raises(ValueError, match="population"):
        FireflyOptions(population=1)


def test_stopping_rule_on_constant_objective():
    r = run(lambda X: np.full(X.shape[0], 3.0), 4, seed=0)
    assert r.stop_reason == "stagnation" and r.iterations == 20        # first iteration checked
    r = run(lambda X: np.full(X.shape[0], 3.0), 4, seed=0, options=FireflyOptions(stop_tol=None))
    assert r.stop_reason == "max_iterations" and r.iterations == 150


def test_stopping_rule_not_triggered_while_mean_fitness_grows():
    calls = [0]

    def evaluate(X):                              # mean fitness grows 1 % per generation
        calls[0] += 1
        return np.full(X.shape[0], 1.01 ** calls[0])

    r = run(evaluate, 3, seed=0)
    assert r.stop_reason == "max_iterations" and r.iterations == 150


# ---------------------------------------------------------------- determinism and resume

def test_same_seed_identical_different_seed_differs():
    f = _fit(rosenbrock)
    a = run(f, 3, seed=42).state.to_dict()
    b = run(f, 3, seed=42).state.to_dict()
    c = run(f, 3, seed=43).state.to_dict()
    assert a == b
    assert a["best_x"] != c["best_x"] and a["population"] != c["population"]


@pytest.mark.parametrize("stop_at", [0, 7, 33])
def test_checkpoint_resume_bit_identical(stop_at):
    f = _fit(rastrigin)
    full = run(f, 2, seed=9)
    saved = {}

    def interrupt(state):
        saved["json"] = state.to_json()
        return state.iteration == stop_at

    part = run(f, 2, seed=9, callback=interrupt)
    assert part.stop_reason == "callback" and part.iterations == stop_at
    obj = Counting(f)
    resumed = run(obj, 2, state=FireflyState.from_json(saved["json"]), seed=12345)  # seed ignored on resume
    assert obj.rows == full.evaluations - 20 * (stop_at + 1)
    assert resumed.state.to_dict() == full.state.to_dict()
    assert resumed.stop_reason == full.stop_reason
    np.testing.assert_array_equal(resumed.x_best, full.x_best)


def test_state_json_round_trip_and_resume_rules():
    r = run(_fit(rosenbrock), 3, seed=2, options=FireflyOptions(max_iterations=10))
    text = r.state.to_json()
    back = FireflyState.from_json(text)
    assert back.to_dict() == r.state.to_dict()
    assert json.loads(text)["rng_state"]["bit_generator"] == "PCG64"
    # extending the iteration budget continues the same trajectory
    longer = run(_fit(rosenbrock), 3, seed=2, options=FireflyOptions(max_iterations=25))
    cont = run(_fit(rosenbrock), 3, state=back, options=FireflyOptions(max_iterations=25))
    assert cont.state.to_dict() == longer.state.to_dict()
    with pytest.raises(ValueError, match="algorithmic"):
        run(_fit(rosenbrock), 3, state=back, options=FireflyOptions(absorption=0.5))
    with pytest.raises(ValueError, match="dimension"):
        run(_fit(rosenbrock), 4, state=back)
    bad = back.to_dict()
    bad["history_mean"] = bad["history_mean"][:-1]
    with pytest.raises(ValueError, match="histories"):
        FireflyState.from_dict(bad)
