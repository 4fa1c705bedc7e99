"""Twin-tube rig damper with mechanisms switched off (attribution of the lumped model's form error).

python -m research.variants VARIANT SEED OUT  -> a dataset as campaign.generate writes it (clean,
--chamber, --t-end 6), from campaign.rig_damper.DamperParams modified by VARIANTS[VARIANT]."""
import sys
from dataclasses import replace
from pathlib import Path

from campaign.rig_damper import DamperParams, PISTON_VALVE

P0 = DamperParams()


def _valves(**kw):
    pv = replace(PISTON_VALVE, **kw)
    ar, aa = P0.area_rod, P0.area_annulus
    return dict(piston_valve=pv, foot_valve=pv.scaled(ar / aa))


VARIANTS = {
    "reference": {},
    # entrained air off: constant bulk modulus 1.55e9 Pa at every pressure
    "no_air": dict(air_fraction=0.0),
    # oil (with the tube compliance) 100x stiffer, no air: chambers practically incompressible
    "stiff_oil": dict(air_fraction=0.0, bulk_modulus=1.55e11),
    # 10x more air (poorly bled damper), to see the trend
    "air_x10": dict(air_fraction=0.01),
    # mounts 100x stiffer, same loss time constant
    "stiff_mounts": dict(mount_stiffness=6e9, mount_damping=1e7),
    # mounts without loss
    "lossless_mounts": dict(mount_damping=1e2),
    # check valves 10x larger and cracking at 1/10 the pressure: near-free venting
    "free_checks": _valves(check_area=300e-6, check_crack=2e3, check_full=8e3, smooth_check=0.5e3),
    # reservoir at high pressure (the chambers never see low pressure)
    "high_res_pressure": dict(gas_pressure=2.0e6),
    # light rod / body
    "light_masses": dict(rod_mass=0.5, body_mass=2.0),
    # combinations
    "no_air_stiff_mounts": dict(air_fraction=0.0, mount_stiffness=6e9, mount_damping=1e7),
    "no_air_high_res": dict(air_fraction=0.0, gas_pressure=2.0e6),
    "stiff_oil_stiff_mounts": dict(air_fraction=0.0, bulk_modulus=1.55e11, mount_stiffness=6e9, mount_damping=1e7),
    "stiff_oil_lossless_mounts": dict(air_fraction=0.0, bulk_modulus=1.55e11, mount_damping=1e2),
    # chambers sealed-stiff ratio: rebound chamber only compliant (compression chamber 100x stiffer)
}


SENSORS = {}  # variant -> SensorChain keyword overrides
SENSORS["no_stroke_noise"] = dict(stroke_noise=0.0)
SENSORS["no_noise"] = dict(stroke_noise=0.0, force_noise=0.0)
EFFECTS = {"friction150": {"friction": 150.0}, "friction60": {"friction": 60.0}, "valve_lag5ms": {"valve_lag": 0.005},
           "inertia": {"inertia": 30.0}}
for _n in EFFECTS:
    VARIANTS[_n] = {}
VARIANTS["no_stroke_noise"] = {}
VARIANTS["no_noise"] = {}


def make(variant: str, seed: int, out: Path, t_end: float = 6.0):
    from campaign.dataset import write_dataset
    from campaign.generate import CHAMBER_TEMPERATURES_C, STROKE_RATE_HZ
    from campaign.rig import measure
    from campaign.scenarios import SCENARIOS, damper_stroke

    from campaign.sensors import SensorChain

    params = replace(P0, **VARIANTS[variant])
    sensors = SensorChain(**SENSORS.get(variant, {}))
    tests = []
    for k, name in enumerate(SCENARIOS):
        sc = SCENARIOS[name]
        t, x, _ = damper_stroke(sc, seed=seed, fs=STROKE_RATE_HZ, t_end=t_end)
        frame = measure(t, x, effects=EFFECTS.get(variant, {}), seed=seed * 1000 + k, sample_rate=1000.0, damper="twin-tube",
                        params=params, oil_temperature=CHAMBER_TEMPERATURES_C[k], sensors=sensors)
        tests.append({"name": name, "role": sc.role, "scenario": sc.description, "frame": frame,
                      "speed_kmh": sc.speed_kmh})
    return write_dataset(out, tests, description=f"twin-tube variant {variant}",
                         generator={"variant": variant, "seed": seed, "t_end_s": t_end, "damper": "twin-tube"},
                         overwrite=True)


if __name__ == "__main__":
    make(sys.argv[1], int(sys.argv[2]), Path(sys.argv[3]))
