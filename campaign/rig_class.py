"""Random physical twin-tube dampers (``campaign.rig_damper``) and rig tests of them with faults hidden in the
damper or in the rig chain after it: data no base model of the tuner made (benchmarks/blind_physical.py).

SI units; stroke positive in extension, force positive in tension.

The damper's priors (one draw per seed from ``numpy.random.default_rng([seed, 3571])``, ``random_rig_damper``):

* piston diameter 40-100 mm, rod/piston area ratio 0.3-0.7; chamber lengths at mid-stroke 70-200 mm each
  (travel: the shorter one less 5 mm), dead volumes 5-30 cm^3;
* oil bulk modulus (with the tube's compliance) 1.2-1.8 GPa, entrained air 0.02-0.5 % by volume (log-uniform);
* reservoir gas 0.15-0.6 MPa absolute, 0.3-2 l, polytropic index 1.0-1.4;
* piston valve: the preset's (``rig_damper.PISTON_VALVE``) reshaped, each part scaled on its own: leakage
  resistance x 0.3-3 and bleed area x 0.5-2, blow-off area x 0.5-2, check crack x 0.5-2 (log-uniform), the
  blow-off crack pressure at a knee force (crack x annulus) log-uniform in 3-20 kN, as the class draws its knee
  (``campaign.damper_class``), full lift at 1.4-2.5 x the crack, the blow-off area at least 1.25 x what carries
  the flow at the tests' top speed (``MAX_VELOCITY``) at full lift (as the preset: full lift above the speeds); flow areas and leakage conductance scaled with
  the annulus area against the preset's (the same pressure drops at the same speeds); the foot valve the piston valve scaled to the
  rod (``ValveSet.scaled``, a symmetric damper) or, on half the seeds, a second valve drawn alike and scaled
  (asymmetric);
* mounts (both ends): stiffness log-uniform 3e6-3e9 N/m (soft rubber to steel), damping log-uniform 1e2-1e6
  N s/m (light to heavy contact; ~critical at 2 sqrt(k m_rod)), the two-chamber base's broad draw
  (``benchmarks/blind_class.BROAD_SERIES``); rod 3-10 kg, body 10-30 kg.

The faults (``RigFaults``, each 0 when off), named by the catalogue magnitude they show as
(``damper_fmu.effect_catalogue``), so that a fitted value compares with the one hidden:

* ``free_play`` [m]: a dead band in the actuator-side mount (``DamperConfig.free_play``); its contact is that
  mount's own stiffness and damping. The reservoir gas pushes the rod out, so at rest the rod bears on one side
  of the gap and the rig tares the gas force there: in the gap the tared force reads minus the static gas force
  (``DamperParams.static_gas_force``, a few hundred N in tension), the catalogue's free play beside a preload;
* ``friction_force`` [N]: rod-seal Coulomb friction between rod and cylinder (``DamperConfig.friction_force``);
* ``valve_tau`` [s]: first-order lag of the blow-off valves' openings (``DamperConfig.valve_tau``);
* ``preload_force`` [N, tension +]: the rig's zero is off by it, the force channel reads ``preload_force`` more
  at every sample: an un-tared share of the reservoir gas force (negative: the gas pushes the rod out) or a
  load-cell offset; the catalogue's preload, a constant force offset;
* ``time_delay`` [s]: the force channel lags the stroke channel (``F(t - delay)``, held at its first value before
  the start), in the rig chain after the damper and before the anti-alias filter and ADC.

Tests (``rig_class_tests``): four identification and two validation tests of 12-16 s, strokes of
``campaign.damper_class``'s generators (``STROKE_KINDS``) capped at its peak velocity (``MAX_VELOCITY``), the
force simulated with the damper's LSODA integrator (``RigDamper.simulate``: the analytic Jacobian and the fast
derivative, as ``campaign.generate`` makes the bundled data) on a grid ``OVERSAMPLING`` x the sample rate, the
static gas force tared, then through the rig's sensor chain (``campaign.sensors``: noise, FIR anti-alias
filter, 16-bit ADC).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, replace

import numpy as np
import pandas as pd

from campaign.damper_class import MAX_VELOCITY, OVERSAMPLING, STROKE_KINDS, capped, random_stroke
from campaign.rig_damper import PISTON_VALVE, DamperConfig, DamperParams, RigDamper, ValveSet
from campaign.sensors import SensorChain
from damper_dataset.writer import write_dataset

__all__ = ["RigFaults", "RigTests", "random_rig_damper", "rig_class_tests", "write_rig_class_dataset",
           "damper_summary", "MOUNT_STIFFNESS_N_M", "MOUNT_DAMPING_N_S_M"]

#: the mounts' stiffness [N/m] and damping [N s/m] ranges (log-uniform)
MOUNT_STIFFNESS_N_M = (3e6, 3e9)
MOUNT_DAMPING_N_S_M = (1e2, 1e6)
#: the blow-off knee's force [N] (crack pressure x annulus; log-uniform): the class's 3-20 kN
#: (``campaign.damper_class``)
KNEE_FORCE_N = (3e3, 2e4)
#: the preset damper's annulus area [m^2], on which the preset valve was fitted
PRESET_ANNULUS_M2 = DamperParams().area_annulus
#: the simulated stroke stays this far [m] inside the damper's travel (``RigDamper.simulate`` refuses more)
TRAVEL_MARGIN = 0.005


def _loguniform(rng, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _random_valve(rng, flow_scale: float, oil_density: float) -> ValveSet:
    """The preset piston valve reshaped (module docstring: each part scaled on its own) for an annulus
    ``flow_scale`` times the preset's: its flow areas and leakage conductance times ``flow_scale`` (the same
    pressure drops at the same piston speeds), its blow-off crack pressure [Pa] a knee force drawn in
    ``KNEE_FORCE_N`` over that annulus; its blow-off area at least what carries the annulus's flow at
    ``MAX_VELOCITY`` at full lift (``oil_density`` [kg/m^3]), as the preset's: full lift above the tests' speeds."""
    crack = _loguniform(rng, *KNEE_FORCE_N) / PRESET_ANNULUS_M2 / flow_scale
    full = crack * rng.uniform(1.4, 2.5)
    check = PISTON_VALVE.check_crack * _loguniform(rng, 0.5, 2.0)
    full_flow = PISTON_VALVE.discharge_coefficient * math.sqrt(2.0 * full / oil_density)  # [m/s] through the area
    area = max(PISTON_VALVE.blowoff_area * _loguniform(rng, 0.5, 2.0) * flow_scale,
               1.25 * flow_scale * PRESET_ANNULUS_M2 * MAX_VELOCITY / full_flow)
    return replace(PISTON_VALVE,
                   laminar_resistance=PISTON_VALVE.laminar_resistance * _loguniform(rng, 0.3, 3.0) / flow_scale,
                   orifice_area=PISTON_VALVE.orifice_area * _loguniform(rng, 0.5, 2.0) * flow_scale,
                   blowoff_crack=crack, blowoff_full=full, blowoff_area=area,
                   check_crack=check, check_full=check * PISTON_VALVE.check_full / PISTON_VALVE.check_crack,
                   check_area=PISTON_VALVE.check_area * flow_scale)


def random_rig_damper(seed: int) -> DamperParams:
    """A random physical twin-tube damper (SI; module docstring: the priors)."""
    rng = np.random.default_rng([seed, 3571])
    d_p = rng.uniform(0.04, 0.1)
    d_r = d_p * math.sqrt(rng.uniform(0.3, 0.7))
    l_r, l_c = rng.uniform(0.07, 0.2), rng.uniform(0.07, 0.2)
    a_rod, a_ann = math.pi / 4 * d_r ** 2, math.pi / 4 * (d_p ** 2 - d_r ** 2)
    rho = DamperParams().oil_density
    piston = _random_valve(rng, a_ann / PRESET_ANNULUS_M2, rho)
    foot = (piston if rng.uniform() < 0.5 else _random_valve(rng, a_ann / PRESET_ANNULUS_M2, rho)).scaled(a_rod / a_ann)
    return DamperParams(
        piston_diameter=d_p, rod_diameter=d_r, rebound_length=l_r, compression_length=l_c,
        dead_volume=rng.uniform(5e-6, 30e-6), travel=min(l_r, l_c) - TRAVEL_MARGIN,
        bulk_modulus=rng.uniform(1.2e9, 1.8e9), air_fraction=_loguniform(rng, 2e-4, 5e-3),
        gas_pressure=rng.uniform(0.15e6, 0.6e6), gas_volume=rng.uniform(0.3e-3, 2e-3), n_gas=rng.uniform(1.0, 1.4),
        piston_valve=piston, foot_valve=foot, mount_stiffness=_loguniform(rng, *MOUNT_STIFFNESS_N_M),
        mount_damping=_loguniform(rng, *MOUNT_DAMPING_N_S_M), rod_mass=rng.uniform(3.0, 10.0),
        body_mass=rng.uniform(10.0, 30.0))


def damper_summary(params: DamperParams) -> dict:
    """The drawn damper in a few numbers (SI, for a benchmark's rows): diameters, chamber lengths, air, gas, mounts,
    the valves' blow-off crack pressures [Pa], the static gas force [N, tension +] the rig tares (a free play's
    dead band shows at minus it in the tared force: the catalogue's un-tared gas force, a preload)."""
    return {"piston_diameter": params.piston_diameter, "rod_diameter": params.rod_diameter,
            "rebound_length": params.rebound_length, "compression_length": params.compression_length,
            "air_fraction": params.air_fraction, "gas_pressure": params.gas_pressure,
            "mount_stiffness": params.mount_stiffness, "mount_damping": params.mount_damping,
            "piston_crack": params.piston_valve.blowoff_crack, "foot_crack": params.foot.blowoff_crack,
            "static_gas_force": params.static_gas_force}


@dataclass(frozen=True)
class RigFaults:
    """Faults hidden in the physical damper or the rig chain (module docstring; SI, 0 = off): free play [m],
    rod-seal friction [N], blow-off valve lag [s], the rig zero's offset [N, tension +], force channel delay [s]."""

    free_play: float = 0.0
    friction_force: float = 0.0
    valve_tau: float = 0.0
    preload_force: float = 0.0
    time_delay: float = 0.0

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not math.isfinite(value) or (name != "preload_force" and value < 0):
                raise ValueError(f"RigFaults.{name} must be finite" + ("" if name == "preload_force" else " and >= 0")
                                 + f", got {value!r}")

    @classmethod
    def of(cls, hidden: dict) -> "RigFaults":
        """From {catalogue magnitude: value} (SI); ValueError naming an unknown key."""
        unknown = sorted(set(hidden) - set(cls.__dataclass_fields__))
        if unknown:
            raise ValueError(f"no rig fault {', '.join(unknown)}; known: {', '.join(cls.__dataclass_fields__)}")
        return cls(**hidden)

    def config(self) -> DamperConfig:
        """The faults that act inside the damper, as its effect switches."""
        return DamperConfig(friction_force=self.friction_force, free_play=self.free_play, valve_tau=self.valve_tau)

    def channel(self, t: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The force [N] the rig chain passes to its sensors: delayed by ``time_delay`` [s] on the grid t [s]
        (held at its first value before the start), offset by ``preload_force`` [N]."""
        out = np.asarray(force, dtype=float)
        if self.time_delay > 0:
            out = np.interp(np.asarray(t) - self.time_delay, t, out, left=out[0])
        return out + self.preload_force


@dataclass(frozen=True)
class RigTests:
    """A damper's rig tests: ``tests`` as ``damper_dataset.writer.write_dataset`` takes them (the recorded
    channels), ``clean`` the force [N] of each test before the rig chain's faults and the sensors, on the
    recorded samples (tension +), ``truth`` the record of what made them (JSON), ``seconds`` the simulation's
    wall time [s]."""

    tests: list
    clean: list
    truth: dict
    seconds: float


def _plan(seed: int, durations) -> tuple[list[float], list[str]]:
    """The seed's test durations [s] (six of 12-16 s unless given) and stroke generators."""
    rng = np.random.default_rng([seed, 7919, 2])
    if durations is None:
        durations = [float(rng.uniform(12.0, 16.0)) for _ in range(6)]
    return list(durations), [STROKE_KINDS[int(rng.integers(len(STROKE_KINDS)))] for _ in durations]


def _stroke(kind: str, seed: int, duration: float, fs: float, travel: float):
    """(time [s], stroke [m]) of one test on the internal grid: capped at ``MAX_VELOCITY`` and inside the travel."""
    t, x, v = random_stroke(kind, seed, duration, fs)
    x, v = capped(x, v, MAX_VELOCITY)
    peak = float(np.max(np.abs(x)))
    if peak > travel - TRAVEL_MARGIN:
        x = x * (travel - TRAVEL_MARGIN) / peak
    n = (t.size - 1) // OVERSAMPLING * OVERSAMPLING + 1
    return t[:n], x[:n]


def rig_class_tests(params: DamperParams, seed: int, *, faults: RigFaults = RigFaults(), sample_rate: float = 500.0,
                    noise_n: float = 25.0, durations=None) -> RigTests:
    """The rig tests of the damper ``params`` with ``faults`` hidden (module docstring): strokes and noise from
    ``seed``, recorded at ``sample_rate`` [Hz] with ``noise_n`` [N rms] on the force; ``durations`` [s]: other
    test lengths (the first two-thirds identification). The same seed gives the same strokes and noise with or
    without faults."""
    if not (sample_rate > 0 and math.isfinite(sample_rate)):
        raise ValueError(f"sample_rate must be a positive number [Hz], got {sample_rate!r}")
    if not (noise_n >= 0 and math.isfinite(noise_n)):
        raise ValueError(f"noise_n must be a non-negative number [N rms], got {noise_n!r}")
    durations, kinds = _plan(seed, durations)
    n_id = max(1, (2 * len(durations)) // 3)
    fs_int = OVERSAMPLING * sample_rate
    damper = RigDamper(params, faults.config())
    tests, clean, t0 = [], [], time.perf_counter()
    for i, (dur, kind) in enumerate(zip(durations, kinds)):
        t, x = _stroke(kind, seed * 100 + i, dur, fs_int, params.travel)
        resp = damper.simulate(t, x)
        force = faults.channel(t, resp.force)
        peak = float(np.abs(force).max())
        chain = SensorChain(force_noise=noise_n, oversampling=OVERSAMPLING,
                            force_range=max(5e3, 2.0 ** math.ceil(math.log2(1.25 * peak))))
        s_out, f_out, _ = chain.acquire(resp.stroke, force, resp.temperature, seed=seed * 100 + i)
        role = "identification" if i < n_id else "validation"
        tests.append({"name": f"{role[:3]}{i + 1}_{kind}", "role": role,
                      "scenario": f"{kind} stroke, force of a random physical twin-tube damper (seed {seed})",
                      "frame": pd.DataFrame({"time": t[::OVERSAMPLING], "stroke": s_out, "force": f_out})})
        clean.append(resp.force[::OVERSAMPLING])
    truth = {"damper": "campaign.rig_class.random_rig_damper", "seed": int(seed), "summary": damper_summary(params),
             "faults": asdict(faults), "noise_n": float(noise_n), "sample_rate_hz": float(sample_rate),
             "kinds": kinds, "durations_s": [float(d) for d in durations]}
    return RigTests(tests, clean, truth, time.perf_counter() - t0)


def write_rig_class_dataset(out_dir, made: RigTests):
    """Write ``made`` (``rig_class_tests``) as a dataset folder, the truth in the manifest's generator; its Path."""
    return write_dataset(out_dir, made.tests, description=f"a random physical twin-tube damper (seed "
                         f"{made.truth['seed']})", generator={"command": "campaign.rig_class.rig_class_tests",
                                                              **made.truth})
