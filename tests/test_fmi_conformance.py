"""The native FMUs driven as different FMI masters drive them (issue 28): the step size as
(k+1)h - kh, ... Each test states the master behaviour it stands for."""
import math

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from damper_fmu.integrator import EXTRAPOLATE, REPLAY, Simulator
from damper_fmu.models import make_model

KINDS = ["lumped", "maxwell", "maxwell_table", "twochamber"]
H = 1e-3


def sine(t, amp=5e-3, freq=5.0):
    w = 2 * np.pi * freq
    return amp * math.sin(w * t), amp * w * math.cos(w * t)


class Slave:
    """One FMU instance through fmpy's raw FMI 2.0 calls."""

    def __init__(self, path, name="damper"):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()

    def start(self, x0=0.0, v0=0.0, t0=0.0, reals=None):
        self.fmu.setupExperiment(startTime=t0)
        self.fmu.enterInitializationMode()
        if reals:
            self.fmu.setReal([self.vr[k] for k in reals], list(reals.values()))
        self.set_inputs(x0, v0)

    def set_inputs(self, x, v):
        self.fmu.setReal([self.vr["stroke"], self.vr["stroke_velocity"]], [x, v])

    def force(self):
        return self.fmu.getReal([self.vr["force"]])[0]

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def stroke_run(path, steps, input_mode=EXTRAPOLATE):
    """Force after each step of a 5 Hz, 5 mm sine; ``steps``: (communication point, step size)
    pairs as the master passes them."""
    s = Slave(path)
    s.start(*sine(0.0))
    if input_mode != EXTRAPOLATE:
        s.fmu.setInteger([s.vr["input_interpolation"]], [input_mode])
    s.fmu.exitInitializationMode()
    out = []
    for k, (t, h) in enumerate(steps):
        # the stroke at this communication point, or at the next one (REPLAY)
        s.set_inputs(*sine((k + 1) * H if input_mode == REPLAY else k * H))
        s.fmu.doStep(t, h)  # fmpy raises on an error status
        out.append(s.force())
    s.close()
    return np.array(out)


def exact_and_jittered(n, h=H):
    exact = [(k * h, h) for k in range(n)]
    # fmpy's simulate_fmu and libcosim: the step is the difference of two communication points
    jittered = [(k * h, (k + 1) * h - k * h) for k in range(n)]
    return exact, jittered


@pytest.mark.parametrize("kind", KINDS)
def test_force_does_not_depend_on_the_last_bits_of_the_step_size(fmu_paths, kind):
    """20 s of a 5 Hz, 5 mm sine: forces with exact steps of 1 ms and with steps of (k+1)h - kh
    (most of which differ from 1 ms by float jitter) are bit-identical."""
    exact, jittered = exact_and_jittered(20000)
    assert sum(h != H for _, h in jittered) > 19000  # the jitter is real
    assert max(abs(h - H) for _, h in jittered) > 1e-12 * H
    for mode in (EXTRAPOLATE, REPLAY):
        a, b = stroke_run(fmu_paths[kind], exact, mode), stroke_run(fmu_paths[kind], jittered, mode)
        assert np.abs(a).max() > 100.0
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("mode", [EXTRAPOLATE, REPLAY])
def test_python_reference_is_equally_independent_of_step_jitter(mode):
    """The Python integrator (behind the pythonfmu FMUs) divides the step the same way."""
    exact, jittered = exact_and_jittered(5000)
    forces = []
    for steps in (exact, jittered):
        sim = Simulator(make_model("lumped"), input_mode=mode)
        sim.initialize(*sine(0.0))
        forces.append([sim.step(h, *sine((k + 1) * H if mode == REPLAY else k * H))
                       for k, (t, h) in enumerate(steps)])
    np.testing.assert_array_equal(*forces)


@pytest.mark.parametrize("tolerance", [0.0, 1e-4])
def test_a_step_a_hair_longer_than_max_step_takes_one_sub_step(tolerance):
    """h = max_step (1 + 1e-15): the same single sub-step as h = max_step, no sliver after it;
    two exact sub-steps of 0.5 ms differ (the division is not ignored)."""
    results = {}
    for h in (H, H * (1 + 1e-15), H * (1 + 4e-12)):
        sim = Simulator(make_model("lumped"), max_step=H, tolerance=tolerance)
        sim.initialize(0.0, 0.1)
        results[h] = [sim.step(h, 1e-4 * k, 0.1) for k in range(5)]
    assert len(set(map(tuple, results.values()))) == 1
    sim = Simulator(make_model("lumped"), max_step=H / 2, tolerance=tolerance)
    sim.initialize(0.0, 0.1)
    assert [sim.step(H, 1e-4 * k, 0.1) for k in range(5)] != results[H]
