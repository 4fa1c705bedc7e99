"""The virtual test campaign end to end: scenarios -> yaw damper strokes -> virtual rig -> dataset.

``generate_dataset(out, seed=2023)`` reproduces the bundled default dataset ``data/default``
bit for bit (same seed, same code). Each of the six scenarios of the paper's Table 1 is run on the
vehicle model (front-right yaw damper stroke at ``STROKE_RATE_HZ``), replayed on the virtual rig
(physical twin-tube damper, hidden effects, sensor chain at ``sample_rate``) and written as one
CSV file with a manifest (``campaign.dataset``). Seeds: the vehicle's track irregularity and the
rig's sensor noise derive from ``seed`` (irregularity: identification and validation
realisations are different streams of the same master seed).
"""
from __future__ import annotations

import time
from pathlib import Path

from .dataset import write_dataset

__all__ = ["generate_dataset", "STROKE_RATE_HZ", "DEFAULT_SEED", "CHAMBER_TEMPERATURES_C"]

STROKE_RATE_HZ = 2000.0
DEFAULT_SEED = 2023
#: A campaign in a climatic chamber: oil temperature [degC] per manoeuvre in the order of
#: ``scenarios.SCENARIOS`` (identification 10 / 25 / 40, validation 15 / 30 / 35), so that a
#: temperature dependence of the damping shows across tests, not only as slow self-heating.
CHAMBER_TEMPERATURES_C = (10.0, 25.0, 40.0, 15.0, 30.0, 35.0)


def generate_dataset(out, *, seed: int = DEFAULT_SEED, effects: dict | None = None,
                     sample_rate: float = 1000.0, scenarios=None, t_end: float | None = None,
                     overwrite: bool = False, damper: str = "twin-tube", oil_temperatures=None,
                     log=print) -> Path:
    """Run the campaign and write a dataset folder; return its path.

    effects: {name: value or None for the documented default} (campaign.effects.EFFECTS);
    sample_rate: rig sample rate [Hz]; scenarios: names to run (default all six);
    t_end: optional shorter duration [s] for quick test datasets; damper: the damper on the rig
    (``campaign.rig.DAMPERS``: the physical ``twin-tube``, or ``lumped`` for the paper's model itself);
    oil_temperatures: optional oil (climatic chamber) temperature [degC] per scenario, a sequence in
    the order of ``scenarios`` or a mapping scenario name -> degC (default: 20 degC for every test).
    """
    from .effects import EFFECTS, validate_effects
    from .rig import DAMPERS, measure
    from .scenarios import SCENARIOS, damper_stroke

    if int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    chosen = list(SCENARIOS) if scenarios is None else list(scenarios)
    unknown = [s for s in chosen if s not in SCENARIOS]
    if unknown:
        raise ValueError(f"unknown scenario(s) {unknown}; known: {list(SCENARIOS)}")
    eff = validate_effects(effects or {})
    if damper not in DAMPERS:
        raise ValueError(f"unknown damper {damper!r}; known: {', '.join(DAMPERS)}")
    if t_end is not None and not (t_end > 0):
        raise ValueError(f"t_end must be a positive duration [s], got {t_end!r}")
    temps = _oil_temperatures(oil_temperatures, chosen)
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise FileExistsError(f"{out} exists and is not empty; use --overwrite to replace it")
    tests = []
    for k, name in enumerate(chosen):
        sc = SCENARIOS[name]
        t0 = time.perf_counter()
        t, x, _ = damper_stroke(sc, seed=seed, fs=STROKE_RATE_HZ, t_end=t_end)
        frame = measure(t, x, effects=eff, seed=seed * 1000 + k, sample_rate=sample_rate,
                        damper=damper, oil_temperature=temps.get(name))
        log(f"  {name:24s} {sc.role:14s} {t[-1]:5.1f} s  peak stroke {1e3 * abs(x).max():5.1f} mm  "
            f"peak force {abs(frame['force']).max() / 1e3:5.1f} kN  ({time.perf_counter() - t0:.1f} s)")
        tests.append({"name": name, "role": sc.role, "scenario": sc.description, "frame": frame,
                      "speed_kmh": sc.speed_kmh})
    generator = {"command": "python -m tuner generate", "seed": int(seed), "sample_rate_hz": float(sample_rate),
                 "stroke_rate_hz": STROKE_RATE_HZ, "effects": {n: eff[n] for n in sorted(eff)},
                 "effect_units": {n: EFFECTS[n].unit for n in sorted(eff)}, "t_end_s": t_end,
                 "vehicle": "campaign.vehicle (7 bodies, linear creep), front-right yaw damper",
                 "damper": damper,
                 **({"oil_temperatures_degC": temps} if temps else {}),
                 "rig": "campaign.rig (" + ("physical twin-tube damper" if damper == "twin-tube" else
                                            "lumped-model damper, Table 2 family") + ", sensor chain)"}
    path = write_dataset(out, tests, description="Virtual test campaign: the six manoeuvres of the paper's "
                         "Table 1 replayed on a virtual damper rig", generator=generator, overwrite=overwrite)
    from .plots import plot_dataset

    log(f"  overview figure: {plot_dataset(path)}")
    return path


def _oil_temperatures(spec, chosen: list[str]) -> dict[str, float]:
    """{scenario: oil temperature [degC]} from a sequence (scenario order) or a mapping; {} for None."""
    if spec is None:
        return {}
    if isinstance(spec, dict):
        unknown = [k for k in spec if k not in chosen]
        if unknown:
            raise ValueError(f"oil temperatures given for scenario(s) not run: {unknown}")
        temps = dict(spec)
    else:
        spec = list(spec)
        if len(spec) != len(chosen):
            raise ValueError(f"{len(spec)} oil temperatures for {len(chosen)} scenarios; give one per scenario")
        temps = dict(zip(chosen, spec))
    from .rig import check_oil_temperature

    return {k: check_oil_temperature(v, f"oil temperature of {k!r}") for k, v in temps.items()}
