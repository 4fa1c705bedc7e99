"""Co-simulation example: a damper FMU coupled through fmpy to a mass on a spring.

    mass m [kg] on a spring k [N/m] to ground, damper between the mass and ground:
    m x'' = -k x - F_damper,     damper stroke = x [m], stroke velocity = x' [m/s],
    F_damper [N] positive in tension (it pulls the mass back when the damper is extended).

Both subsystems are stepped at one fixed communication step h [s], as a multibody code does:
the master sends the mass state at t_n to the FMU (co-simulation input convention,
``input_interpolation = 0``), the FMU returns its force at t_n + h, and the mass is advanced
over [t_n, t_n + h] exactly (matrix exponential of the mass-spring system) under that force held
constant (zero-order hold). The one-step coupling delay is the usual explicit co-simulation error;
it vanishes as h -> 0.

Run it from the project folder (it builds the preset lumped FMU into build/fmu/ when missing):

    python examples/mass_spring_cosim.py [FMU] [--t-end S] [--step S]
"""
from __future__ import annotations

import argparse
import shutil

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from scipy.linalg import expm

from damper_fmu.fmu import ensure_fmu

__all__ = ["mass_spring_cosimulation"]


def _zoh_matrices(m: float, k: float, h: float):
    """Exact discretisation of x'' = -(k/m) x + u/m with u [N] held over h [s]: (A, B)."""
    a = np.array([[0.0, 1.0, 0.0], [-k / m, 0.0, 1.0 / m], [0.0, 0.0, 0.0]])
    e = expm(a * h)
    return e[:2, :2], e[:2, 2]


def mass_spring_cosimulation(fmu_path, *, mass: float, stiffness: float, x0: float, v0: float = 0.0,
                             h: float = 1e-3, t_end: float = 2.0, params: dict | None = None):
    """Run the coupled system; return a dict of arrays time [s], x [m], v [m/s], force [N].

    mass [kg], stiffness [N/m], x0 [m] and v0 [m/s] the initial state, h [s] the communication step,
    t_end [s]; ``params``: damper FMU parameter values (SI) applied before initialisation.
    """
    if not (mass > 0 and stiffness > 0 and h > 0 and t_end > h):
        raise ValueError("mass, stiffness, h must be positive and t_end > h")
    md = read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = extract(str(fmu_path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="damper")
    try:
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        if params:
            fmu.setReal([vr[n] for n in params], [float(v) for v in params.values()])
        if "input_interpolation" in vr:
            fmu.setInteger([vr["input_interpolation"]], [0])
        fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x0, v0])
        fmu.exitInitializationMode()
        a, b = _zoh_matrices(mass, stiffness, h)
        n = int(round(t_end / h))
        t = np.arange(n + 1) * h
        state = np.array([x0, v0])
        xs, vs, fs = np.empty(n + 1), np.empty(n + 1), np.empty(n + 1)
        xs[0], vs[0] = x0, v0
        fs[0] = fmu.getReal([vr["force"]])[0]
        for i in range(n):
            fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [state[0], state[1]])
            fmu.doStep(currentCommunicationPoint=t[i], communicationStepSize=h)
            f = fmu.getReal([vr["force"]])[0]
            state = a @ state + b * (-f)
            xs[i + 1], vs[i + 1], fs[i + 1] = state[0], state[1], f
        fmu.terminate()
    finally:
        fmu.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
    return {"time": t, "x": xs, "v": vs, "force": fs}


def main(argv=None) -> int:
    """A 500 kg mass on a 2e6 N/m spring released from 10 mm, with the damper FMU between it and ground."""
    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("fmu", nargs="?", help="a damper FMU (default: the preset lumped FMU, built when missing)")
    ap.add_argument("--t-end", type=float, default=2.0, help="simulated time [s]")
    ap.add_argument("--step", type=float, default=1e-3, help="communication step [s]")
    args = ap.parse_args(argv)
    fmu = args.fmu or ensure_fmu("lumped")
    res = mass_spring_cosimulation(fmu, mass=500.0, stiffness=2e6, x0=0.01, h=args.step, t_end=args.t_end)
    peak = np.abs(res["force"]).max()
    print(f"{fmu}: peak damper force {peak / 1e3:.2f} kN; displacement {1e3 * res['x'][0]:.2f} mm at 0 s, "
          f"{1e3 * res['x'][-1]:.3f} mm at {res['time'][-1]:g} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
