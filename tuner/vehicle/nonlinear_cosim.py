"""The nonlinear car of :mod:`campaign.vehicle_nonlinear` (saturating creep, flange contact) as
co-simulation master of four yaw damper FMUs, for hunting limit cycles.

The coupling is that of :mod:`tuner.vehicle.cosim` (same signs: ``stroke`` [m] the damper's elongation,
extension positive, ``stroke_velocity`` [m/s] its rate, ``force`` [N] tension positive; the damper pulls
its bogie and carbody brackets together with ``-E^T F``), with one difference: the vehicle is nonlinear
and cannot be advanced by a matrix exponential. Communication step ``h`` (1 ms), at ``t_k = k h``:

1. each damper FMU gets the elongation and its rate at ``t_k`` and, where it interpolates its inputs,
   the elongation's acceleration at ``t_k`` from the vehicle's equations (with the force at ``t_k``);
2. ``fmi2DoStep(t_k, h)``; the force at ``t_{k+1}`` is read;
3. the vehicle advances over ``[t_k, t_{k+1}]`` by ``substeps`` classical Runge-Kutta steps with each
   damper force linear between its values at ``t_k`` and ``t_{k+1}`` (the Runge-Kutta stages see the
   interpolated force at their own times).

Accuracy is checked in ``tests/test_vehicle_nonlinear_cosim.py`` against the built-in Maxwell damper
of the same car solved by ``solve_ivp`` (DOP853, rtol 1e-10). The loop runs in C
(``tuner/vehicle/c/nonlinear_master.c``: the vehicle's matrices and the contact's formulas, the FMUs' own
FMI functions called without the interpreter) where a C compiler is found, else the same arithmetic
and calls from Python (tested equal).
"""
from __future__ import annotations

import ctypes
import math

import numpy as np

from campaign.vehicle import N_BODIES, N_DAMPERS, N_DOF, N_STATES, WHEELSETS, VehicleParams
from campaign.vehicle_nonlinear import N_MECH, ContactSettings, NonlinearRun, NonlinearVehicle
from tuner.vehicle.cosim import DEFAULT_STEP, FmuDampers, compiled_loop, rk4_linear_forces

__all__ = ["NonlinearCosim", "nonlinear_master_loop"]


def nonlinear_master_loop():
    """The compiled C master loop of the nonlinear car (ctypes function), or None without a C compiler."""
    dp, ip, vp = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_void_p)
    return compiled_loop("nonlinear_master", "nonlinear_vehicle_run",
                         [ctypes.c_int] * 6 + [dp] * 4 + [ip, dp, dp, ctypes.c_double] + [vp] * 5
                         + [ctypes.POINTER(ctypes.c_uint), dp, dp, ip, ip])


class NonlinearCosim(FmuDampers):
    """The nonlinear car ``params`` / ``settings`` with four yaw damper FMUs at the communication step
    ``step`` [s], ``substeps`` Runge-Kutta steps of the vehicle per communication step.

    ``fmus``: one path (four instances) or four in ``DAMPER_NAMES`` order; ``fmu_parameters``: FMU
    parameter name -> SI value applied to every damper before each run; ``c_loop``: the C master loop
    where a compiler is found. Use as a context manager or call :meth:`close`."""

    def __init__(self, fmus, *, params: VehicleParams | None = None, settings: ContactSettings | None = None,
                 step: float = DEFAULT_STEP, substeps: int = 1, fmu_parameters: dict | None = None,
                 c_loop: bool = True):
        paths = self.damper_paths(fmus)
        if not (math.isfinite(step) and 0.0 < step <= 2e-3):
            raise ValueError(f"communication step must be in (0, 2 ms], got {step} s")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.params = params if params is not None else VehicleParams()
        self.settings = settings
        self.step, self.substeps = float(step), substeps
        self._loop = nonlinear_master_loop() if c_loop else None
        self.open_dampers(paths, fmu_parameters)

    def run(self, speed: float, x0: np.ndarray, t_end: float) -> NonlinearRun:
        """Run at ``speed`` [m/s] on straight ideal track for ``t_end`` [s] from the state ``x0``
        (N_MECH or N_STATES values; damper forces in it are ignored: each FMU starts afresh at the
        elongation and rate of ``x0``). Returns the states (n, N_STATES) with the FMU forces [N] in the
        last four columns, every communication step."""
        x = np.array(x0, dtype=float)[:N_MECH]
        if x.shape != (N_MECH,) or not np.all(np.isfinite(x)):
            raise ValueError(f"x0 must hold at least {N_MECH} finite values")
        if not (math.isfinite(t_end) and t_end >= self.step):
            raise ValueError(f"t_end must be >= the communication step {self.step} s, got {t_end}")
        model = NonlinearVehicle(self.params, speed, self.settings)
        E = model.linear.E
        h, m = self.step, self.substeps
        n = int(round(t_end / h))
        out = np.empty((n + 1, N_STATES))
        F = np.array([d.start(0.0, float(e), float(v))
                      for d, e, v in zip(self.dampers, E @ x[:N_DOF], E @ x[N_DOF:])])
        out[0, :N_MECH], out[0, N_MECH:] = x, F
        if self._loop is not None:
            X, Fs = self._run_c(model, n, out[0, :N_MECH], F)
            out[:, :N_MECH], out[:, N_MECH:] = X, Fs
        else:
            for k in range(n):
                t = k * h
                dx = model.mechanical_rhs(x, F)
                e, v, a = E @ x[:N_DOF], E @ x[N_DOF:], E @ dx[N_DOF:]
                F1 = np.array([d.step(t, h, e[i], v[i], a[i]) for i, d in enumerate(self.dampers)])
                x = rk4_linear_forces(model.mechanical_rhs, x, F, F1, h, m, dx)
                F = F1
                out[k + 1, :N_MECH], out[k + 1, N_MECH:] = x, F
        return NonlinearRun(np.arange(n + 1) * h, out, model.speed)

    def _run_c(self, model: NonlinearVehicle, n: int, x0: np.ndarray, F0: np.ndarray):
        """The same steps in C (``c/nonlinear_master.c``): states (n + 1, N_MECH) and forces (n + 1, 4)."""
        nd, c = N_DAMPERS, model.contact
        X = np.zeros((n + 1, N_MECH))
        Fs = np.zeros((n + 1, nd))
        X[0], Fs[0] = x0, F0
        arr = (lambda a: np.ascontiguousarray(a, dtype=float))  # noqa: E731
        Am, Af, E = arr(model.A[:N_MECH, :N_MECH]), arr(model.A[:N_MECH, N_MECH:]), arr(model.linear.E[:, :N_DOF])
        cp = arr([c.conicity, c.wheel_radius, c.contact_half_distance, c.f11, c.f22, c.creep_limit(),
                  c.flange_clearance, c.flange_stiffness, model.speed])
        wi = np.ascontiguousarray(WHEELSETS, dtype=np.intc)
        inv_m, inv_i = arr(1.0 / model.linear.mass[list(WHEELSETS)]), arr(1.0 / model.linear.inertia[list(WHEELSETS)])
        vp = ctypes.c_void_p * nd
        fns = [vp(*[d.fn[j] for d in self.dampers]) for j in range(3)]
        sd = vp(*[d.der_ptr for d in self.dampers])
        comp = vp(*[d.runner._component for d in self.dampers])
        vr = (ctypes.c_uint * (3 * nd))(*[v for d in self.dampers for v in d.vr])
        dp, ip = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
        ptr = (lambda a: a.ctypes.data_as(dp))  # noqa: E731
        fstep, fdamp = ctypes.c_int(0), ctypes.c_int(0)
        st = self._loop(n, self.substeps, N_MECH, nd, len(WHEELSETS), N_BODIES, ptr(Am), ptr(Af), ptr(E), ptr(cp),
                        wi.ctypes.data_as(ip), ptr(inv_m), ptr(inv_i), self.step, fns[0], sd, fns[1], fns[2], comp,
                        vr, ptr(X), ptr(Fs), ctypes.byref(fstep), ctypes.byref(fdamp))
        if st == 3:
            raise ValueError("vehicle too large for the C master loop")
        if st > 1:
            d = self.dampers[fdamp.value]
            d.runner._check(st, f"damper {d.name}, step {fstep.value} (t = {fstep.value * self.step:.6g} s)")
        return X, Fs

    def runner(self):
        """This co-simulation as the ``runner(speed, x0, duration)`` of :mod:`campaign.bifurcation`."""
        return self.run
