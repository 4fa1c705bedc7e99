"""The identification problem: the rig tests prepared once, for every stage that uses them.

``Problem.build(identification, validation, DataSettings(...))`` resamples and differentiates every
test (``prepared_signals``, over ``tuner.data.preprocess.prepare``), turns them into engine signals, and
derives what the fit, the diagnosis, the batch runner and the benchmarks all need from the data: the peak
force [N], the stroke range [m], the damper's scale (``tuner.identification.damper_scale``: every bound and fixed
constant of the models follows it), the force noise in the fit band [N rms], the table abscissae, the Fc,O force
limit [N], the Fk,O reference spring [N/m] and a digest for resuming. ``problem.parametrization(kind)`` gives the
design space of a model on it. One place, so that the stages cannot disagree about the data (before: the fit and the
diagnosis each prepared the tests, and the diagnosis ignored ``--force-limit``).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, fields, replace

import numpy as np

from damper_fmu.parameters import FC_ABSCISSAE, FK_ABSCISSAE, FK_REFERENCE_STIFFNESS, MODEL_PARAMETERS, densify_abscissae

from tuner.data.noise import pooled_noise
from tuner.data.prefilter import parse_prefilter
from tuner.data.preprocess import prepare
from tuner.data.reading import RigTest
from tuner.identification.damper_scale import DamperScale, spring_reference
from tuner.identification.engine import IDENTIFICATION_STEP, Signals, oversampling
from tuner.identification.floor import ResidualFloor, stroke_sigmas
from tuner.identification.parametrization import Parametrization

__all__ = ["DataSettings", "split_data_settings", "Problem", "prepared_signals", "to_signals", "table_abscissae",
           "model_abscissae", "default_force_limit", "data_digest", "STRETCH_BEYOND"]

#: The tables keep the paper's Table 2 abscissae until the data reach this many times the last one.
STRETCH_BEYOND = 1.5


@dataclass(frozen=True)
class DataSettings:
    """How the rig tests become an identification problem (units in the names).

    fit_rate_hz: rate the tests are resampled to (anti-aliased) and compared at; warmup_s: samples
    before time[0] + warmup_s do not count; diff_band_hz: band [Hz] within which the stroke
    differentiator is accurate to 0.5 % (None: from each test's stroke spectrum); damping/elastic
    abscissae: the Fc,O rates [m/s] (14) and Fk,O elongations [m] (10), None: from the data;
    force_limit_n: cap on the Fc,O ordinates (None: ``default_force_limit``); spring_reference_n_per_m: the
    Fk,O ordinates' reference spring (None: the paper's 1.5e7 N/m mapped to the damper's scale,
    ``damper_scale.spring_reference``); parametrization:
    'improved' (monotone tables, needed by the local solver) or 'paper'; sim_step_s: the grid [s] the model is
    simulated on (fixed sub-steps of that size, its force low-passed to the fit rate): 1 ms integrates a smooth
    damper to a fraction of a newton, but a gap closing on stiff silent blocks only to tens of newtons (a
    0.132 mm gap in 4.9e7 N/m blocks: the true parameters at 48.2 N against 41.7 N at 0.1 ms and 41.5 N
    converged), which shows up as biased or false small causes beside the free play (docs/identification.md)."""

    fit_rate_hz: float = 200.0
    warmup_s: float = 0.5
    diff_band_hz: float | None = None
    damping_abscissae_m_s: tuple | None = None
    elastic_abscissae_m: tuple | None = None
    force_limit_n: float | None = None
    spring_reference_n_per_m: float | None = None
    parametrization: str = "improved"
    sim_step_s: float = IDENTIFICATION_STEP

    @property
    def internal_step_s(self) -> float:
        """The longest fixed sub-step of the identification's simulations [s]: ``sim_step_s``, at most
        ``IDENTIFICATION_STEP`` (on data compared at its own rate, not oversampled, the sub-steps make the grid)."""
        return min(self.sim_step_s, IDENTIFICATION_STEP)

    def to_dict(self) -> dict:
        """The fields by name (SI values as given; the abscissae as tuples or None)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def split_data_settings(flat: dict) -> tuple[DataSettings, dict]:
    """(the ``DataSettings`` of the problem-definition keys of ``flat``, a new dict of the other keys): a
    flat settings record read back (``FitSettings.to_dict``, a fleet row, metrics.json "settings" of any
    run). The abscissae come back as tuples (JSON gives lists)."""
    names = {f.name for f in fields(DataSettings)}
    data = {k: v for k, v in flat.items() if k in names}
    for k in ("damping_abscissae_m_s", "elastic_abscissae_m"):
        if data.get(k) is not None:
            data[k] = tuple(data[k])
    return DataSettings(**data), {k: v for k, v in flat.items() if k not in names}


def to_signals(p, warmup_s: float, oversample: int | None = None, sim_step_s: float = IDENTIFICATION_STEP) -> Signals:
    """Engine input from a PreparedTest; samples before time[0] + warmup_s do not count.

    A filter the lab declared (``metadata['read']['prefilter']``, ``tuner.data.prefilter``) goes with the
    signals, and the samples within its settling time do not count either.

    oversample: factor of the band-limited comparison (``tuner.identification.engine``); by default the one that
    puts the simulation grid at ``sim_step_s`` [s] when the data was low-passed to the fit rate, else 1 (data
    at its own rate, not filtered). Samples the low-pass does not fully cover
    (tens of ms at each end) do not count either.
    """
    if oversample is None:
        oversample = oversampling(p.sample_rate, sim_step_s) if p.resampler is not None else 1
    lab_filter = parse_prefilter((p.metadata.get("read", {}).get("prefilter") or {}).get("spec"))
    since = p.time - p.time[0]
    mask = since >= max(warmup_s, lab_filter.settling_s if lab_filter else 0.0)
    stroke, velocity = p.stroke, p.stroke_velocity
    if lab_filter is not None and (lab_filter.zero_phase or not lab_filter.force_only):
        mask &= since <= since[-1] - lab_filter.settling_s  # settling (or the undone filter's edge) at the end too
    if lab_filter is not None and not lab_filter.force_only:  # the model is driven by the stroke before the filter
        stroke, velocity = (lab_filter.unapply(a, p.sample_rate) for a in (p.stroke, p.stroke_velocity))
    temp = p.channels.get("temperature")
    s = Signals(p.name, p.time, stroke, velocity, p.force, mask,
                None if temp is None else np.asarray(temp, dtype=float), int(oversample), lab_filter)
    k0, n = s.band_limited_span()
    mask[:k0] = False
    mask[k0 + n:] = False
    if mask.sum() < 10:
        raise ValueError(f"test {p.name!r}: warm-up of {warmup_s} s leaves fewer than 10 samples")
    return s


def prepared_signals(tests: list[RigTest], settings: DataSettings,
                     rate_hz: float | None = None) -> tuple[list, list[Signals]]:
    """The ``tests`` as the fit prepares them: (PreparedTests, their engine signals). Resampled to ``rate_hz``
    [Hz] (None: the settings' ``fit_rate_hz``; the full-rate check compares at another rate), the stroke
    differentiated within the settings' ``diff_band_hz`` [Hz] (``tuner.data.preprocess.prepare``), then
    :func:`to_signals` (the first ``warmup_s`` [s] do not count). The one place the tests are prepared:
    ``Problem.build``, the full-rate check and the rig test design's candidates all come here. Every test
    is prepared before any becomes signals."""
    rate = settings.fit_rate_hz if rate_hz is None else rate_hz
    prepared = [prepare(t, rate, diff_band_hz=settings.diff_band_hz) for t in tests]
    return prepared, [to_signals(p, settings.warmup_s, sim_step_s=settings.sim_step_s) for p in prepared]


def _given(name: str, values, preset: tuple) -> tuple:
    xs = tuple(float(v) for v in values)
    if len(xs) != len(preset) or any(x == 0 for x in xs) or list(xs) != sorted(xs) or \
            sum(x < 0 for x in xs) != sum(x < 0 for x in preset):
        raise ValueError(f"{name}: need {len(preset)} increasing nonzero values, {sum(x < 0 for x in preset)} of "
                         f"them negative (like Table 2's {preset}), got {xs}")
    return xs


def table_abscissae(tests: list[Signals], peak_force: float, spring_reference: float = FK_REFERENCE_STIFFNESS,
                    damping=None, elastic=None) -> dict:
    """Fixed abscissae of the Fc,O [m/s] and Fk,O [m] tables for this data, as parameter values.

    Table 2's layout unless the data go beyond it: when the identification tests' peak stroke
    velocity exceeds ``STRETCH_BEYOND`` x the last rate abscissa (100 mm/s), every rate abscissa
    is stretched by the same factor so that the last one is 5 % above the peak (the knee region
    keeps its share of points); the elongation abscissae likewise when the reference spring's
    elongation at the peak force, ``peak_force / spring_reference``, exceeds 1.5 x the last one
    (2 mm). Up to 1.5 x the last piece is extrapolated by its fitted slope; the paper's layout is
    kept there so the tables compare with Table 2. ``damping``/``elastic``: abscissae given by
    the user (SI), used as they are.
    """
    vpeak = max(float(np.max(np.abs(s.stroke_velocity[s.mask]))) for s in tests)
    if damping is not None:
        fc = _given("damping abscissae", damping, FC_ABSCISSAE)
    else:
        last = max(abs(v) for v in FC_ABSCISSAE)
        k = 1.05 * vpeak / last if vpeak > STRETCH_BEYOND * last else 1.0
        fc = tuple(v * k for v in FC_ABSCISSAE)
    if elastic is not None:
        fk = _given("elastic abscissae", elastic, FK_ABSCISSAE)
    else:
        last = max(abs(x) for x in FK_ABSCISSAE)
        e = peak_force / spring_reference
        k = 1.05 * e / last if e > STRETCH_BEYOND * last else 1.0
        fk = tuple(x * k for x in FK_ABSCISSAE)
    out = {f"Fc_v{i:02d}": v for i, v in enumerate(fc, start=1)}
    out.update({f"Fk_x{i:02d}": x for i, x in enumerate(fk, start=1)})
    return out


def default_force_limit(tests: list[Signals], axes: dict) -> float:
    """Limit [N] of the damping table's ordinates (``Parametrization.force_limit``) for these tests and the
    :func:`table_abscissae` ``axes``: 1.5 x the identification tests' peak force, times the ratio of the
    last rate abscissa to the data's peak stroke velocity where the data do not reach it (the ordinates
    beyond the data extrapolate the table; a random damper whose data reached 59 of 100 mm/s had its
    100 mm/s ordinate at 1.6 x the peak force, and the plain 1.5 x cap held the fit 4.5x above the floor).
    Two significant digits."""
    peak = max(float(np.abs(s.force[s.mask]).max()) for s in tests)
    vpeak = max(float(np.max(np.abs(s.stroke_velocity[s.mask]))) for s in tests)
    vlast = max(abs(v) for k, v in axes.items() if k.startswith("Fc_v"))
    return float(f"{1.5 * peak * max(1.0, vlast / max(vpeak, 1e-12)):.2g}")


def model_abscissae(model: str, axes: dict) -> dict:
    """The fixed abscissae of ``model`` from the :func:`table_abscissae` of the data: the lumped and
    table-Maxwell models take them as they are; the two-chamber model's damping table has the
    midpoints added (``damper_fmu.parameters.densify_abscissae``)."""
    names = {p.name for p in MODEL_PARAMETERS[model]}
    if model == "twochamber":
        fc = [axes[k] for k in sorted(axes) if k.startswith("Fc_v")]
        return {f"Fc_v{i:02d}": v for i, v in enumerate(densify_abscissae(fc), start=1)}
    return {k: v for k, v in axes.items() if k in names}


def _scale_and_axes(sig_id: list[Signals], peak: float, stroke_range: float,
                    settings: DataSettings) -> tuple[DamperScale, float, dict]:
    """(the damper's scale, the Fk,O reference spring [N/m], the :func:`table_abscissae`) of the identification
    signals of peak |force| ``peak`` [N] and stroke range ``stroke_range`` [m]: the scale's velocity span is the
    damping table's (its rates do not depend on the spring), the spring the settings' or the scale's, and the
    elastic abscissae follow that spring."""
    rates = table_abscissae(sig_id, peak, damping=settings.damping_abscissae_m_s)
    scale = DamperScale.of(peak, stroke_range, rates)
    spring = settings.spring_reference_n_per_m or spring_reference(scale)
    axes = table_abscissae(sig_id, peak, spring, settings.damping_abscissae_m_s, settings.elastic_abscissae_m)
    return scale, spring, axes


def data_digest(tests: list[RigTest]) -> str:
    h = hashlib.sha256()
    for t in tests:
        h.update(t.name.encode())
        for a in (t.time, t.stroke, t.force):
            h.update(np.ascontiguousarray(a).tobytes())
        lab_filter = (t.metadata.get("read") or {}).get("prefilter")
        if lab_filter:  # compared through it
            h.update(lab_filter["spec"].encode())
    return h.hexdigest()


@dataclass
class Problem:
    """Rig tests prepared for identification and validation (build with ``Problem.build``).

    prep_id/prep_val: the PreparedTests (fit rate, differentiated stroke); sig_id/sig_val: their
    engine signals; peak_n: peak |force| of the identification tests [N] (counted samples);
    stroke_range_m: the largest stroke range of an identification test [m]; noise_n: force noise in
    the fit band [N rms] of the identification tests; noise: how it was estimated, whether it is
    credible and why (``tuner.data.noise.pooled_noise``: per test the estimate used, cycle scatter or
    quiet band, and every estimate made); axes: the table abscissae (``table_abscissae``);
    force_limit_n: the Fc,O ordinate cap [N] (the settings' or ``default_force_limit``); scale: the damper's
    (``DamperScale``: peak force, stroke range, the damping table's rate span), which every bound and fixed
    constant of the models follows; spring_reference_n_per_m: the Fk,O ordinates' reference spring [N/m] (the
    settings' or the scale's); digest: of the identification data (resume keys)."""

    settings: DataSettings
    identification: list
    validation: list
    prep_id: list = field(repr=False)
    prep_val: list = field(repr=False)
    sig_id: list = field(repr=False)
    sig_val: list = field(repr=False)
    peak_n: float
    stroke_range_m: float
    noise_n: float
    axes: dict
    force_limit_n: float
    digest: str
    scale: DamperScale
    spring_reference_n_per_m: float
    noise: dict = field(default_factory=dict, repr=False)

    @classmethod
    def build(cls, identification: list[RigTest], validation: list[RigTest],
              settings: DataSettings | None = None) -> "Problem":
        settings = settings or DataSettings()
        if not identification:
            raise ValueError("no identification test given")
        n = len(identification)
        prep, sig = prepared_signals([*identification, *validation], settings)
        prep_id, prep_val, sig_id, sig_val = prep[:n], prep[n:], sig[:n], sig[n:]
        peak = max(float(np.abs(s.force[s.mask]).max()) for s in sig_id)
        stroke_range = max(float(np.ptp(s.stroke[s.mask])) for s in sig_id)
        scale, spring, axes = _scale_and_axes(sig_id, peak, stroke_range, settings)
        noise = pooled_noise(identification, settings.fit_rate_hz, settings.warmup_s)
        return cls(settings=settings, identification=list(identification), validation=list(validation),
                   prep_id=prep_id, prep_val=prep_val, sig_id=sig_id, sig_val=sig_val, peak_n=peak,
                   stroke_range_m=stroke_range, noise_n=noise["in_band_n"], noise=noise, axes=axes,
                   force_limit_n=settings.force_limit_n or default_force_limit(sig_id, axes),
                   digest=data_digest(identification), scale=scale, spring_reference_n_per_m=spring)

    def parametrization(self, kind: str, fixed_from: dict | None = None, scheme: str | None = None) -> Parametrization:
        """The design space of model ``kind`` on this data: the table abscissae fixed (those of
        ``fixed_from``, an earlier fit's values, where given), the force limit and scheme of the
        settings (``scheme`` overrides it)."""
        fixed = model_abscissae(kind, self.axes)
        if fixed_from is not None:
            fixed = {k: fixed_from.get(k, v) for k, v in fixed.items()}
        return Parametrization(kind, scheme or self.settings.parametrization, force_limit=self.force_limit_n,
                               spring_reference=self.spring_reference_n_per_m, fixed=fixed, scale=self.scale)

    def on_grid(self, step_s: float) -> "Problem":
        """This problem with the model simulated on a grid of ``step_s`` [s] (``DataSettings.sim_step_s``): the same
        prepared tests, noise and tables, the engine signals made again."""
        settings = replace(self.settings, sim_step_s=step_s)
        sig_id, sig_val = ([to_signals(p, settings.warmup_s, sim_step_s=step_s) for p in prep]
                           for prep in (self.prep_id, self.prep_val))
        return replace(self, settings=settings, sig_id=sig_id, sig_val=sig_val)

    def residual_floor(self, engine: str = "fmu") -> ResidualFloor:
        """The residual floor of this problem's identification tests (``tuner.identification.floor``): the force
        noise, whether it is credible, and the stroke channel's noise of each test, simulated with ``engine``."""
        return ResidualFloor(self.noise_n, bool(self.noise.get("credible", True)), self.sig_id,
                             stroke_sigmas(self.identification, self.settings.fit_rate_hz), engine)
