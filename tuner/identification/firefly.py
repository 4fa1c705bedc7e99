"""Firefly algorithm as stated by Isacchi, Ripamonti & Corsi (2023), section 2.3 and 3.1.

The optimiser *maximises* a fitness G (in our use G = N / SSE [1/N^2], eq. 5) over
scaled design variables x in [0, 1]^d. The objective is a batch function
``evaluate(X) -> G`` with X of shape (n, d); it is called exactly once per generation
so the caller may evaluate the n candidates in parallel and count evaluations.
Non-finite fitness (a failed simulation) is treated as the worst value, 0.

Paper rules kept as printed: population P = 20, at most 150 iterations, absorption
eps = 0.8, rho = rho0^(k-1) with rho0 = 0.9 (k = 1, 2, ... is the move iteration),
d_ij Euclidean in scaled space (eq. 7), only strictly brighter fireflies attract
(M = number of j with G_j > G_i), best-ever individual stored.

Interpretations of what the paper leaves open (all configurable in FireflyOptions):

1. Random term, eq. 8. The bounds L_min = -x_new, L_max = 1 - x_new refer to the
   position being built. We compute the attraction part first,
   ``x_att = x_i + sum_j beta_ij (x_j - x_i)``, clip it to [0, 1], then draw ONE random
   vector per move, R ~ U[-x_att, 1 - x_att] per coordinate, and set
   ``x_new = x_att + rho R``. The paper says R "is calculated for each modification of
   an i-esimal individual", and one draw per move is the only reading that keeps the
   move inside [0, 1] for any M: with 0 <= rho <= 1, x_new = (1 - rho) x_att + rho U with
   U ~ U[0, 1], a convex blend. M independent draws (one per attraction term) would
   add up to M rho (1 - x_att) and leave the box. A final clip to [0, 1] only guards
   against round-off. Consequence worth knowing: at k = 1 (rho = 1) every moving
   firefly is redrawn uniformly, and the random term pulls towards the box centre with
   weight rho; the search is effectively global for ~10 iterations and local after ~40.
2. G0 (not given). Default: G0 = g0 / M with g0 = 2 (``normalise_g0=True``), i.e.
   beta_ij = (2/M) / (1 + eps d_ij^2). Normalising by M bounds the total pull by g0
   whatever the number of brighter fireflies; with the classic beta0 = 1 per term
   (``normalise_g0=False, g0=1``) the worst firefly adds up to 19 full pulls and its
   attraction point leaves the box in 34-67 % of the coordinates during the first 20
   iterations (then clipped). g0 = 1 makes x_att a convex combination inside the
   brighter fireflies' hull, so the swarm can only contract, and with the paper's
   fast rho decay it contracts prematurely; g0 = 2 lets a firefly pass beyond the
   weighted mean of its brighter neighbours (at most a reflection through it).
   Experiment (paper budget 20 x 150, 20-30 seeds, optimum uniform in [0.1, 0.9]^d,
   median / worst best-f): shifted sphere 5-D g0=1: 1.1e-2 / 5.8e-2, g0=2: 1.5e-3 /
   4.2e-3, classic: 2.4e-3 / 2.1e-2; Rosenbrock 3-D ([-2,2]^3): 0.61 / 1.17, 0.020 /
   0.46, 0.94 / 4.0; ellipsoid 10-D (weights 1..1e4): 12 / 81, 0.22 / 6.9, 12 / 42;
   shifted Rastrigin 2-D, share reaching the global basin: 10 %, 70 %, 17 %. Classic
   was better only on the 29-D ellipsoid (median 131 vs 192, g0=1: 396). The attraction
   point is clipped to [0, 1] before the random term is drawn.
3. The brightest firefly (M = 0) has an empty sum in eq. 6 and therefore stays
   (``brightest_moves=False``, the literal reading; it is re-evaluated with its
   generation so the count stays P per iteration). ``brightest_moves=True`` gives it
   the random term alone.
4. Stopping rule (printed garbled as "stop if G_k < 0.001 sum_{t=k-20}^{k} G_mean,t / 20").
   Read as the gradient test the text describes: from iteration k >= 20, stop when
   |G_mean,k - mean(G_mean,k-20 .. G_mean,k-1)| <= tol * mean(...), tol = 1e-3. The
   window holds the 20 previous generations (generation 0 = initial population).
   ``stop_tol=None`` disables it.
5. Synchronous update: all moves of a generation are computed from the old population
   and old fitness, then the new generation is evaluated in one batch and replaces
   the old one entirely (no greedy selection; the best-ever is stored separately).

Reproducibility: a numpy Generator seeded once; its ``bit_generator.state`` is part
of FireflyState, which serialises to JSON exactly (floats round-trip through repr),
so a run checkpointed after any iteration and resumed gives a bit-identical result.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields
from typing import Any, Callable

import numpy as np

__all__ = ["FireflyOptions", "FireflyState", "FireflyResult", "run", "move_population"]

# options that change the trajectory; they must not change when a run is resumed
_ALGORITHMIC = ("population", "absorption", "rho0", "g0", "normalise_g0", "brightest_moves")
STOP_REASONS = ("max_iterations", "stagnation", "callback", "max_evaluations")


@dataclass(frozen=True)
class FireflyOptions:
    """Algorithm settings (paper values by default; all dimensionless).

    population: P, fireflies per generation. max_iterations: move iterations after the
    initial generation. absorption: eps of eq. 6. rho0: rho = rho0^(k-1). g0: attractiveness
    G0; normalise_g0 divides it by the number M of brighter fireflies (the classic
    beta0 = 1 is normalise_g0=False, g0=1). brightest_moves:
    the brightest gets the random term alone instead of staying. stop_start, stop_window,
    stop_tol: stagnation test (see module docstring); stop_tol=None disables it.
    """

    population: int = 20
    max_iterations: int = 150
    absorption: float = 0.8
    rho0: float = 0.9
    g0: float = 2.0
    normalise_g0: bool = True
    brightest_moves: bool = False
    stop_start: int = 20
    stop_window: int = 20
    stop_tol: float | None = 1e-3

    def __post_init__(self) -> None:
        if int(self.population) != self.population or self.population < 2:
            raise ValueError(f"population must be an integer >= 2, got {self.population!r}")
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 0:
            raise ValueError(f"max_iterations must be an integer >= 0, got {self.max_iterations!r}")
        if not (math.isfinite(self.absorption) and self.absorption >= 0):
            raise ValueError(f"absorption must be finite and >= 0, got {self.absorption!r}")
        if not (0.0 <= self.rho0 <= 1.0):
            raise ValueError(f"rho0 must lie in [0, 1] so rho <= 1 keeps moves in the box, got {self.rho0!r}")
        if not (math.isfinite(self.g0) and self.g0 >= 0):
            raise ValueError(f"g0 must be finite and >= 0, got {self.g0!r}")
        if int(self.stop_start) != self.stop_start or self.stop_start < 1:
            raise ValueError(f"stop_start must be an integer >= 1, got {self.stop_start!r}")
        if int(self.stop_window) != self.stop_window or self.stop_window < 1:
            raise ValueError(f"stop_window must be an integer >= 1, got {self.stop_window!r}")
        if self.stop_tol is not None and not (math.isfinite(self.stop_tol) and self.stop_tol >= 0):
            raise ValueError(f"stop_tol must be None or finite and >= 0, got {self.stop_tol!r}")

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "FireflyOptions":
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown FireflyOptions fields: {sorted(unknown)}")
        return cls(**data)


@dataclass
class FireflyState:
    """Complete, serialisable state after a finished iteration.

    population (P, d) and best_x (d,) are scaled variables in [0, 1]; fitness (P,) and
    best_fitness are G (after replacing non-finite values by 0). iteration = number of
    completed move iterations (0 = only the initial generation evaluated). History lists
    are indexed by generation t = 0..iteration: mean and max fitness of generation t,
    best-ever fitness after t, and cumulative objective evaluations after t.
    """

    options: FireflyOptions
    population: np.ndarray
    fitness: np.ndarray
    best_x: np.ndarray
    best_fitness: float
    iteration: int
    evaluations: int
    rng_state: dict[str, Any]
    history_mean: list[float] = field(default_factory=list)
    history_generation_best: list[float] = field(default_factory=list)
    history_best: list[float] = field(default_factory=list)
    history_evaluations: list[int] = field(default_factory=list)
    stop_reason: str | None = None

    @property
    def dimension(self) -> int:
        return int(self.population.shape[1])

    def copy(self) -> "FireflyState":
        return FireflyState.from_dict(self.to_dict())

    def to_dict(self) -> dict[str, Any]:
        return {
            "options": self.options.to_dict(),
            "population": self.population.tolist(),
            "fitness": self.fitness.tolist(),
            "best_x": self.best_x.tolist(),
            "best_fitness": float(self.best_fitness),
            "iteration": int(self.iteration),
            "evaluations": int(self.evaluations),
            "rng_state": json.loads(json.dumps(self.rng_state)),
            "history_mean": [float(v) for v in self.history_mean],
            "history_generation_best": [float(v) for v in self.history_generation_best],
            "history_best": [float(v) for v in self.history_best],
            "history_evaluations": [int(v) for v in self.history_evaluations],
            "stop_reason": self.stop_reason,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "FireflyState":
        try:
            state = cls(
                options=FireflyOptions.from_dict(dict(data["options"])),
                population=np.array(data["population"], dtype=float),
                fitness=np.array(data["fitness"], dtype=float),
                best_x=np.array(data["best_x"], dtype=float),
                best_fitness=float(data["best_fitness"]),
                iteration=int(data["iteration"]),
                evaluations=int(data["evaluations"]),
                rng_state=json.loads(json.dumps(data["rng_state"])),
                history_mean=[float(v) for v in data["history_mean"]],
                history_generation_best=[float(v) for v in data["history_generation_best"]],
                history_best=[float(v) for v in data["history_best"]],
                history_evaluations=[int(v) for v in data["history_evaluations"]],
                stop_reason=data.get("stop_reason"),
            )
        except KeyError as exc:
            raise ValueError(f"FireflyState data lacks field {exc.args[0]!r}") from None
        state._check()
        return state

    def to_json(self) -> str:
        return json.dumps(self.to_dict())

    @classmethod
    def from_json(cls, text: str) -> "FireflyState":
        return cls.from_dict(json.loads(text))

    def _check(self) -> None:
        P = self.options.population
        if self.population.ndim != 2 or self.population.shape[0] != P:
            raise ValueError(f"state population must have shape ({P}, d), got {self.population.shape}")
        d = self.population.shape[1]
        if self.fitness.shape != (P,) or self.best_x.shape != (d,):
            raise ValueError("state fitness/best_x shapes do not match the population")
        n = self.iteration + 1
        hist = (self.history_mean, self.history_generation_best, self.history_best, self.history_evaluations)
        if any(len(h) != n for h in hist):
            raise ValueError(f"state histories must have iteration + 1 = {n} entries")
        if self.stop_reason is not None and self.stop_reason not in STOP_REASONS:
            raise ValueError(f"unknown stop_reason {self.stop_reason!r}")


@dataclass
class FireflyResult:
    """Outcome of run(): best-ever scaled point x_best (d,) in [0, 1], its fitness G,
    the final state (resumable), and why the run stopped."""

    x_best: np.ndarray
    fitness_best: float
    iterations: int
    evaluations: int
    stop_reason: str
    state: FireflyState

    @property
    def history_mean(self) -> np.ndarray:
        return np.asarray(self.state.history_mean)

    @property
    def history_best(self) -> np.ndarray:
        return np.asarray(self.state.history_best)


def move_population(X: np.ndarray, G: np.ndarray, rho: float, options: FireflyOptions,
                    rng: np.random.Generator) -> np.ndarray:
    """One synchronous Firefly move (eqs. 6-8) of the whole population.

    X: (P, d) scaled positions in [0, 1]; G: (P,) fitness (finite); rho: random weight in
    [0, 1]. Draws exactly one (P, d) block of uniforms from rng whatever the ranking, so
    the random stream does not depend on the fitness values. Returns the new (P, d).
    """
    P, d = X.shape
    U = rng.random((P, d))
    diff = X[None, :, :] - X[:, None, :]              # [i, j] = x_j - x_i
    d2 = np.einsum("ijk,ijk->ij", diff, diff)         # squared distances, eq. 7
    brighter = G[None, :] > G[:, None]                # [i, j] = G_j > G_i
    m = brighter.sum(axis=1)
    beta = np.where(brighter, options.g0 / (1.0 + options.absorption * d2), 0.0)
    if options.normalise_g0:
        beta = beta / np.maximum(m, 1)[:, None]
    x_att = np.clip(X + np.einsum("ij,ijk->ik", beta, diff), 0.0, 1.0)
    x_new = x_att + rho * (U - x_att)                 # R = U - x_att ~ U[-x_att, 1 - x_att]
    moves = np.ones(P, dtype=bool) if options.brightest_moves else m > 0
    return np.clip(np.where(moves[:, None], x_new, X), 0.0, 1.0)


def _evaluate(evaluate: Callable[[np.ndarray], np.ndarray], X: np.ndarray) -> np.ndarray:
    G = np.asarray(evaluate(X.copy()), dtype=float)
    if G.shape != (X.shape[0],):
        raise ValueError(f"evaluate must return fitness of shape ({X.shape[0]},), got {G.shape}")
    G = np.where(np.isfinite(G), G, 0.0)
    if np.any(G < 0):
        raise ValueError(f"fitness must be >= 0 (G = N / SSE), got min {G.min()!r}")
    return G


def _initial_population(rng: np.random.Generator, P: int, d: int, initial: np.ndarray | None) -> np.ndarray:
    X = rng.random((P, d))
    if initial is not None:
        init = np.atleast_2d(np.asarray(initial, dtype=float))
        if init.ndim != 2 or init.shape[1] != d:
            raise ValueError(f"initial population must have shape (m, {d}), got {np.shape(initial)}")
        if init.shape[0] > P:
            raise ValueError(f"initial population has {init.shape[0]} rows, more than population {P}")
        if not np.all(np.isfinite(init)) or init.min() < 0 or init.max() > 1:
            raise ValueError("initial population must be finite scaled values within [0, 1]")
        X[: init.shape[0]] = init
    return X


def _record(state: FireflyState) -> None:
    G = state.fitness
    i = int(np.argmax(G))
    if G[i] > state.best_fitness:
        state.best_fitness = float(G[i])
        state.best_x = state.population[i].copy()
    state.history_mean.append(float(G.mean()))
    state.history_generation_best.append(float(G[i]))
    state.history_best.append(float(state.best_fitness))
    state.history_evaluations.append(int(state.evaluations))


def _algorithmic_stop(state: FireflyState, options: FireflyOptions) -> str | None:
    if state.iteration >= options.max_iterations:
        return "max_iterations"
    k, w = state.iteration, options.stop_window
    if options.stop_tol is not None and k >= max(options.stop_start, w):
        ref = float(np.mean(state.history_mean[-w - 1:-1]))
        if abs(state.history_mean[-1] - ref) <= options.stop_tol * ref:
            return "stagnation"
    return None


def _make_rng(rng_state: dict[str, Any]) -> np.random.Generator:
    name = rng_state.get("bit_generator")
    bitgen_cls = getattr(np.random, str(name), None)
    if bitgen_cls is None or not isinstance(bitgen_cls, type) or not issubclass(bitgen_cls, np.random.BitGenerator):
        raise ValueError(f"unknown bit generator {name!r} in state")
    bitgen = bitgen_cls()
    bitgen.state = rng_state
    return np.random.Generator(bitgen)


def run(evaluate: Callable[[np.ndarray], np.ndarray], d: int, *, options: FireflyOptions | None = None,
        seed: int | None = None, state: FireflyState | None = None,
        callback: Callable[[FireflyState], bool | None] | None = None,
        max_evaluations: int | None = None, initial: np.ndarray | None = None) -> FireflyResult:
    """Maximise fitness G over [0, 1]^d with the paper's Firefly algorithm.

    evaluate(X) -> G: X (n, d) scaled in [0, 1], G (n,) fitness >= 0 (non-finite -> 0);
    called once per generation. d: number of design variables. seed: for
    numpy.random.default_rng (ignored when resuming). state: resume from a saved
    FireflyState (its options are used when options is None; algorithmic options must
    match, stopping options may change). callback(state) runs after the initial
    generation and after every iteration, once the stop decision is made
    (state.stop_reason); returning True stops the run; it must not mutate state.
    max_evaluations: no generation is started that would exceed it. initial: (m, d)
    scaled individuals, m <= P, placed first in the initial population (rest uniform).
    """
    if int(d) != d or d < 1:
        raise ValueError(f"d must be a positive integer, got {d!r}")
    d = int(d)
    if max_evaluations is not None and (int(max_evaluations) != max_evaluations or max_evaluations < 0):
        raise ValueError(f"max_evaluations must be a non-negative integer, got {max_evaluations!r}")

    if state is None:
        opts = options if options is not None else FireflyOptions()
        P = opts.population
        if max_evaluations is not None and max_evaluations < P:
            raise ValueError(f"max_evaluations={max_evaluations} is below one generation ({P})")
        rng = np.random.default_rng(seed)
        X = _initial_population(rng, P, d, initial)
        G = _evaluate(evaluate, X)
        st = FireflyState(options=opts, population=X, fitness=G, best_x=X[0].copy(), best_fitness=-math.inf,
                          iteration=0, evaluations=P, rng_state={})
        _record(st)
        st.rng_state = rng.bit_generator.state
        st.stop_reason = _algorithmic_stop(st, opts)
        if callback is not None and callback(st) and st.stop_reason is None:
            st.stop_reason = "callback"
    else:
        if initial is not None:
            raise ValueError("initial population cannot be given when resuming from a state")
        st = state.copy()
        if st.dimension != d:
            raise ValueError(f"state has dimension {st.dimension}, run was asked for d={d}")
        opts = options if options is not None else st.options
        changed = [n for n in _ALGORITHMIC if getattr(opts, n) != getattr(st.options, n)]
        if changed:
            raise ValueError(f"cannot resume with changed algorithmic options: {changed}")
        st.options = opts
        rng = _make_rng(st.rng_state)
        st.stop_reason = _algorithmic_stop(st, opts)

    P = opts.population
    while st.stop_reason is None:
        if max_evaluations is not None and st.evaluations + P > max_evaluations:
            st.stop_reason = "max_evaluations"
            break
        k = st.iteration + 1
        rho = opts.rho0 ** (k - 1)
        X = move_population(st.population, st.fitness, rho, opts, rng)
        G = _evaluate(evaluate, X)
        st.population, st.fitness = X, G
        st.iteration = k
        st.evaluations += P
        st.rng_state = rng.bit_generator.state
        _record(st)
        st.stop_reason = _algorithmic_stop(st, opts)
        if callback is not None and callback(st) and st.stop_reason is None:
            st.stop_reason = "callback"

    return FireflyResult(x_best=st.best_x.copy(), fitness_best=float(st.best_fitness), iterations=st.iteration,
                         evaluations=st.evaluations, stop_reason=str(st.stop_reason), state=st)
