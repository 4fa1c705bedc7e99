"""Benchmark: cost of one communication step of the damper FMUs, measured side by side.

    python benchmarks/bench_fmu_step.py [--seconds 10] [--repeats 7]

Prints, per communication step (1 kHz stroke, 2 Hz + 7 Hz sine):
  (1) the lumped-model FMU (native where a C compiler is found) through tuner.identification.runner.FmuRunner
      (C stepping loop), (2) the lumped pythonfmu FMU through the same runner, (3) an empty
      pythonfmu FMU with the same interface through the same runner (pythonfmu's FMI boundary
      alone), (4) the lumped FMU through a warm fmpy.simulate_fmu (+ reset) as FMU calibration
      tools drive FMUs, and (5) damper_fmu.simulate without FMI (the C kernel where compiled).
The variants are interleaved repeat by repeat and the median is reported, so machine load hits
them alike. Targets (issue 2): (2)/(3) <= 2, (4)/(1) >= 2.
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from damper_fmu.fmu import ensure_fmu  # noqa: E402
from damper_fmu import simulate  # noqa: E402
from tuner.identification.runner import FmuRunner  # noqa: E402


def stroke(seconds: float, fs: float = 1000.0):
    t = np.arange(0.0, seconds, 1.0 / fs)
    w1, w2 = 2 * np.pi * 2.0, 2 * np.pi * 7.0
    x = 2e-3 * np.sin(w1 * t) + 5e-4 * np.sin(w2 * t)
    v = 2e-3 * w1 * np.cos(w1 * t) + 5e-4 * w2 * np.cos(w2 * t)
    return t, x, v


class SimulateFmuWay:
    """A warm fmpy.simulate_fmu on one reused instance, reset between runs."""

    def __init__(self, path: Path):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(str(path))
        self.unzip = extract(str(path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzip,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="warm")
        self.fmu.instantiate()
        self.first = True

    def run(self, t, x, v):
        from fmpy import simulate_fmu

        if not self.first:
            self.fmu.reset()
        self.first = False
        names = [("time", float), ("stroke", float), ("stroke_velocity", float)]
        inputs = {v.name for v in self.md.modelVariables if v.causality == "input"}
        if "oil_temperature" in inputs:
            names.append(("oil_temperature", float))
        signals = np.zeros(t.size, dtype=names)
        signals["time"], signals["stroke"], signals["stroke_velocity"] = t, x, v
        if "oil_temperature" in inputs:
            signals["oil_temperature"] = 20.0  # unused unless thermal_source = 1
        h = float(t[1] - t[0])
        res = simulate_fmu(self.unzip, model_description=self.md, fmu_instance=self.fmu, start_time=float(t[0]),
                           stop_time=float(t[-1]), step_size=h, output_interval=h, input=signals,
                           start_values={"input_interpolation": 1}, output=["force"], terminate=False)
        return res["force"]

    def close(self):
        self.fmu.freeInstance()
        shutil.rmtree(self.unzip, ignore_errors=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated stroke length per run [s]")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    t, x, v = stroke(args.seconds)
    lumped, empty = FmuRunner(ensure_fmu("lumped")), FmuRunner(ensure_fmu("empty"))
    lumped_py = FmuRunner(ensure_fmu("lumped", flavour="python"))
    warm = SimulateFmuWay(ensure_fmu("lumped"))
    variants = {
        "lumped FMU, runner": lambda: lumped.run(t, x, v),
        "lumped pythonfmu FMU, runner": lambda: lumped_py.run(t, x, v),
        "empty pythonfmu FMU, runner": lambda: empty.run(t, x, v),
        "lumped FMU, warm simulate_fmu+reset": lambda: warm.run(t, x, v),
        "damper_fmu.simulate (no FMI)": lambda: simulate("lumped", t, x, v),
    }
    for f in variants.values():  # warm-up
        f()
    times = {k: [] for k in variants}
    for _ in range(args.repeats):
        for name, f in variants.items():
            t0 = time.perf_counter()
            f()
            times[name].append((time.perf_counter() - t0) / (t.size - 1))
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"per communication step, median of {args.repeats} interleaved runs of {t.size} steps:")
    for name, value in med.items():
        print(f"  {name:40s} {value * 1e6:8.2f} us")
    r1 = med["lumped pythonfmu FMU, runner"] / med["empty pythonfmu FMU, runner"]
    r2 = med["lumped FMU, warm simulate_fmu+reset"] / med["lumped FMU, runner"]
    print(f"lumped / empty pythonfmu FMU step (target <= 2.0):   {r1:5.2f}")
    print(f"lumped pythonfmu / lumped FMU (native) step:          {med['lumped pythonfmu FMU, runner'] / med['lumped FMU, runner']:5.1f}")
    print(f"warm simulate_fmu / our runner per run (target >= 2): {r2:5.2f}")
    lumped.close(), empty.close(), warm.close()
    return 0 if (r1 <= 2.0 and r2 >= 2.0) else 1


if __name__ == "__main__":
    sys.exit(main())
