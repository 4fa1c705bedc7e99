"""The vehicle of :mod:`campaign.vehicle` as co-simulation master of four yaw damper FMUs.

Design: the vehicle's equations are the ones of :class:`campaign.vehicle.VehicleModel` (seven rigid
bodies, lateral and yaw, linear creep, primary and secondary suspension), without its built-in
Maxwell yaw dampers: their four forces become inputs, taken from the FMUs. The vehicle part is linear,
so it is integrated *exactly* over each communication step ``h`` (matrix exponential, first-order
hold on the track inputs and on the damper forces); the only co-simulation error is the coupling.

Sign conventions (those of the FMUs, ``damper_fmu.parameters``, and of :mod:`campaign.vehicle`):
damper ``stroke`` [m] is the elongation, positive in extension, ``stroke_velocity`` [m/s] its rate,
``force`` [N] positive in tension. The front right damper's elongation is
``d (Psi_front_bogie - Psi_carbody)`` (lateral offset ``d``, see ``VehicleModel.E``); a tension
force pulls its two brackets together, i.e. acts on the bogie and the carbody with the equal and
opposite yaw moments ``-/+ d F`` (``-E^T F`` in the generalised forces).

Coupling at step k (``t_k = k h``), the vehicle as master:

1. every damper FMU gets the elongation and its rate from the bogie-carbody kinematics at ``t_k``
   (co-simulation convention, ``input_interpolation = 0``) and, where the FMU can interpolate its
   inputs (``canInterpolateInputs``), the elongation acceleration at ``t_k`` from the vehicle's
   equations as the first derivative of ``stroke_velocity``, so the FMU follows the stroke over the
   step to second order instead of holding it;
2. ``fmi2DoStep(t_k, h)``; the force at ``t_{k+1}`` is read;
3. the vehicle advances over ``[t_k, t_{k+1}]`` with each damper force linear between its values at
   ``t_k`` and ``t_{k+1}``.

The stepping loop runs in C (``tuner/vehicle/c/vehicle_master.c``, the FMUs' own FMI functions called
without the interpreter) where a C compiler is found, else the same calls from Python.
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from fmpy import read_model_description

from campaign.vehicle import DAMPER_NAMES, DT_MAX, N_BODIES, N_DAMPERS, N_DOF, VehicleModel, VehicleParams
from damper_fmu.native import compile_library
from tuner.identification.runner import FmuRunner

__all__ = ["VehicleCosim", "VehicleRun", "DamperInstance", "reference_run", "check_damper_fmu", "master_loop",
           "compiled_loop", "FmuDampers", "N_MECH", "DEFAULT_STEP", "rk4_linear_forces"]

N_MECH = 2 * N_DOF
"""Mechanical states of the vehicle: y_0..y_6, Psi_0..Psi_6 [m, rad], their rates [m/s, rad/s]."""
DEFAULT_STEP = 1e-3
"""Default communication step [s]."""
_LOOPS: dict = {}


def compiled_loop(source: str, symbol: str, argtypes: list):
    """The C function ``symbol`` of ``c/<source>.c`` beside this module, compiled once and cached, with its
    ctypes ``argtypes`` and an int result; None without a C compiler (the callers then loop in Python)."""
    if symbol not in _LOOPS:
        try:
            lib = ctypes.CDLL(str(compile_library(Path(__file__).resolve().parent / "c" / f"{source}.c", source)))
            fn = getattr(lib, symbol)
            fn.argtypes, fn.restype = argtypes, ctypes.c_int
        except OSError:
            fn = None
        _LOOPS[symbol] = fn
    return _LOOPS[symbol]


def master_loop():
    """The compiled C master loop of the linear vehicle (ctypes function), or None without a C compiler."""
    dp, ip, vp = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_void_p)
    return compiled_loop("vehicle_master", "vehicle_run",
                         [ctypes.c_int] * 3 + [dp] * 9 + [ctypes.c_double] * 2 + [vp] * 5
                         + [ctypes.POINTER(ctypes.c_uint), dp, dp, ip, ctypes.c_int, ctypes.c_double, ip, ip, ip])


def check_damper_fmu(path) -> None:
    """Raise FileNotFoundError (missing file) or ValueError naming ``path`` and the variable when the
    FMU is not an FMI 2.0 co-simulation FMU with the inputs ``stroke`` [m], ``stroke_velocity`` [m/s]
    and the output ``force`` [N] of a damper."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"damper FMU not found: {path}")
    try:
        md = read_model_description(str(path))
    except Exception as err:  # noqa: BLE001 - fmpy raises various types on a broken archive
        raise ValueError(f"{path}: not a readable FMU ({err})") from None
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise ValueError(f"{path}: need an FMI 2.0 co-simulation FMU, got FMI {md.fmiVersion} "
                         f"{'without co-simulation' if md.coSimulation is None else ''}".rstrip())
    variables = {v.name: v for v in md.modelVariables}
    for name, causality in (("stroke", "input"), ("stroke_velocity", "input"), ("force", "output")):
        v = variables.get(name)
        if v is None:
            raise ValueError(f"{path}: no variable '{name}' (a yaw damper FMU needs the inputs stroke [m], "
                             f"stroke_velocity [m/s] and the output force [N])")
        if v.causality != causality or v.type != "Real":
            raise ValueError(f"{path}: variable '{name}' must be a Real {causality}, is a {v.type} {v.causality}")


@dataclass
class VehicleRun:
    """One vehicle run on the communication grid ``t`` [s] (from 0).

    ``states`` (n, 28): y_0..y_6 [m], Psi_0..Psi_6 [rad] (absolute headings, see campaign.vehicle),
    their rates; ``forces`` (n, 4) [N] yaw damper forces, tension positive, columns in
    ``DAMPER_NAMES`` order; ``inputs`` (n, N_INPUTS) the track inputs; ``completed``: False when the
    run was stopped early by its amplitude limit (then the arrays end there)."""

    t: np.ndarray
    states: np.ndarray
    forces: np.ndarray
    inputs: np.ndarray
    model: VehicleModel
    track: object
    s0: float
    completed: bool = True

    @property
    def strokes(self) -> np.ndarray:
        """Damper elongations [m] (n, 4), extension positive."""
        return self.states[:, :N_DOF] @ self.model.E.T

    @property
    def stroke_velocities(self) -> np.ndarray:
        """Damper elongation rates [m/s] (n, 4)."""
        return self.states[:, N_DOF:] @ self.model.E.T

    def _stations(self) -> np.ndarray:
        return self.s0 + self.model.speed * self.t[:, None] + self.model.p.positions[None, :]

    @property
    def bogie_yaw(self) -> np.ndarray:
        """Yaw angles [rad] of the front and rear bogie (n, 2) relative to the track tangent at their
        centres, positive to the left (counter-clockwise seen from above)."""
        th = self.track.heading(self._stations()[:, 1:3])
        return self.states[:, N_BODIES + 1:N_BODIES + 3] - th

    @property
    def carbody_lateral_acceleration(self) -> np.ndarray:
        """Lateral acceleration [m/s^2] an accelerometer on the carbody measures in the track plane:
        ``y_0'' + V^2 kappa - g h / 1.5`` (positive to the left, +y)."""
        m = self.model
        i = N_DOF
        acc = (self.states @ m.A[i, :N_MECH] + self.inputs @ m.B[i] + self.forces @ m.A[i, N_MECH:])
        return acc + self.inputs[:, 8]  # input 8: the carbody's uncompensated acceleration

    @property
    def wheelset_lateral(self) -> np.ndarray:
        """Lateral displacements [m] of the four wheelsets relative to the track (n, 4)."""
        return self.states[:, 3:7]


class DamperInstance:
    """One damper FMU instance (extracted and instantiated once, reset for every run)."""

    def __init__(self, path, name: str, parameters: dict | None):
        check_damper_fmu(path)
        self.name = name
        self.runner = r = FmuRunner(path, input_mode=0, instance_name=f"yaw_damper_{name}", c_loop=False)
        self.parameters = dict(parameters or {})
        unknown = [p for p in self.parameters if p not in r.parameter_names]
        if unknown:
            raise ValueError(f"{r.path}: no parameter(s) {unknown}")
        self.vr = [r.variables[n].valueReference for n in ("stroke", "stroke_velocity", "force")]
        dll = r.fmu.dll
        self.set_der = None
        if r.md.coSimulation.canInterpolateInputs:
            self.set_der = dll.fmi2SetRealInputDerivatives
        self.fn = [ctypes.cast(f, ctypes.c_void_p).value for f in (r._set_real, r._do_step, r._get_real)]
        self.der_ptr = ctypes.cast(self.set_der, ctypes.c_void_p).value if self.set_der is not None else None
        self._buf = None

    def start(self, t0: float, stroke: float, velocity: float) -> float:
        """Reset, apply the parameters, initialise at (``stroke`` [m], ``velocity`` [m/s]); the force [N]."""
        r = self.runner
        inp = (ctypes.c_double * 2)(stroke, velocity)
        r._start(t0, self.parameters or None, r._vr_in, inp)
        buf = (ctypes.c_double * 1)()
        r._check(r._get_real(r._component, (ctypes.c_uint * 1)(self.vr[2]), 1, buf), "reading the initial force")
        return float(buf[0])

    def step(self, t: float, h: float, stroke: float, velocity: float, acceleration: float) -> float:
        """One communication step from ``t`` over ``h`` [s] with the elongation ``stroke`` [m], its rate
        ``velocity`` [m/s] and (where the FMU interpolates its inputs) rate of change ``acceleration``
        [m/s^2] at ``t``; the force [N] at ``t + h``. Raises SimulationError naming the damper on failure."""
        r, c = self.runner, self.runner._component
        if self._buf is None:
            self._buf = ((ctypes.c_uint * 2)(self.vr[0], self.vr[1]), (ctypes.c_uint * 1)(self.vr[1]),
                         (ctypes.c_uint * 1)(self.vr[2]), (ctypes.c_double * 2)(), (ctypes.c_double * 1)(),
                         (ctypes.c_double * 1)(), (ctypes.c_int * 1)(1))
        vr_in, vr_v, vr_f, inp, acc, out, order = self._buf
        inp[0], inp[1], acc[0] = stroke, velocity, acceleration
        r._check(r._set_real(c, vr_in, 2, inp), f"damper {self.name}: setting inputs at t = {t:.6g} s")
        if self.set_der is not None:
            r._check(self.set_der(c, vr_v, 1, order, acc), f"damper {self.name}: input derivative at t = {t:.6g} s")
        r._check(r._do_step(c, t, h, 1), f"damper {self.name}: step at t = {t:.6g} s")
        r._check(r._get_real(c, vr_f, 1, out), f"damper {self.name}: reading the force at t = {t + h:.6g} s")
        return float(out[0])

    def close(self):
        self.runner.close()


class FmuDampers:
    """The four yaw damper FMU instances of a car's co-simulation (``DAMPER_NAMES`` order), what the linear
    (``VehicleCosim``) and the nonlinear car (``tuner.vehicle.nonlinear_cosim``) share: opening them, closing
    them, the context manager."""

    @staticmethod
    def damper_paths(fmus) -> list[Path]:
        """One path (four instances of it) or four paths in ``DAMPER_NAMES`` order; ValueError otherwise."""
        paths = [fmus] if isinstance(fmus, (str, Path)) else list(fmus)
        if len(paths) == 1:
            paths = paths * N_DAMPERS
        if len(paths) != N_DAMPERS:
            raise ValueError(f"give one damper FMU or {N_DAMPERS} ({', '.join(DAMPER_NAMES)}), got {len(paths)}")
        return [Path(p) for p in paths]

    def open_dampers(self, paths: list[Path], fmu_parameters: dict | None) -> None:
        """An instance of each FMU of ``paths`` (all closed again if one fails)."""
        self.paths = list(paths)
        self.dampers: list[DamperInstance] = []
        try:
            for p, name in zip(self.paths, DAMPER_NAMES):
                self.dampers.append(DamperInstance(p, name, fmu_parameters))
        except BaseException:
            self.close()
            raise

    def close(self):
        """Free the FMU instances and their extracted files."""
        for d in self.dampers:
            d.close()
        self.dampers = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class VehicleCosim(FmuDampers):
    """The vehicle with four yaw damper FMUs, stepped at the communication step ``step`` [s].

    ``fmus``: one path (four instances of it) or four paths in ``DAMPER_NAMES`` order (front right,
    front left, rear right, rear left); each must have the inputs ``stroke`` [m], ``stroke_velocity``
    [m/s] and the output ``force`` [N]. ``params``: the vehicle (:class:`VehicleParams`; its yaw damper
    fields are not used). ``fmu_parameters``: FMU parameter name -> SI value applied to every damper
    before each run (the others keep the FMU's start values). ``c_loop``: the C master loop where a
    compiler is found. Use as a context manager or call :meth:`close`.
    """

    def __init__(self, fmus, *, params: VehicleParams | None = None, step: float = DEFAULT_STEP,
                 fmu_parameters: dict | None = None, c_loop: bool = True):
        paths = self.damper_paths(fmus)
        if not (math.isfinite(step) and 0.0 < step <= 0.01):
            raise ValueError(f"communication step must be in (0, 10 ms], got {step} s")
        self.params = params if params is not None else VehicleParams()
        self.step = float(step)
        self.open_dampers(paths, fmu_parameters)
        self._loop = master_loop() if c_loop else None
        self._disc: dict = {}

    def set_fmu_parameters(self, fmu_parameters: dict | None) -> None:
        """FMU parameter name -> SI value applied to every damper before each later run, instead of those
        given so far (the others keep the FMU's start values): one vehicle, many damper parameter sets,
        without re-extracting the FMUs. ValueError naming the FMU and the unknown parameters."""
        new = dict(fmu_parameters or {})
        for d in self.dampers:
            unknown = [p for p in new if p not in d.runner.parameter_names]
            if unknown:
                raise ValueError(f"{d.runner.path}: no parameter(s) {unknown}")
        for d in self.dampers:
            d.parameters = dict(new)

    # -- discretisation ---------------------------------------------------------------------------
    def _matrices(self, speed: float):
        key = float(speed)
        if key not in self._disc:
            from scipy.linalg import expm

            model = VehicleModel(self.params, speed)
            nx, nd, h = N_MECH, N_DAMPERS, self.step
            A = model.A[:nx, :nx]
            Bf = model.A[:nx, nx:nx + nd]
            Bu = model.B[:nx]
            nu = Bu.shape[1]
            m = nu + nd
            Z = np.zeros((nx + 2 * m, nx + 2 * m))
            Z[:nx, :nx] = A * h
            Z[:nx, nx:nx + m] = np.hstack([Bu, Bf]) * h
            Z[nx:nx + m, nx + m:] = np.eye(m)
            X = expm(Z)
            Phi, G1, G2 = X[:nx, :nx], X[:nx, nx:nx + m], X[:nx, nx + m:]
            E = model.E
            Ex = np.hstack([E, np.zeros_like(E)])
            Ev = np.hstack([np.zeros_like(E), E])
            vel = slice(N_DOF, nx)
            mats = dict(model=model, Phi=Phi, G1u=G1[:, :nu] - G2[:, :nu], G2u=G2[:, :nu],
                        G1f=G1[:, nu:] - G2[:, nu:], G2f=G2[:, nu:], Ex=Ex, Ev=Ev, Ea=E @ A[vel],
                        EBu=E @ Bu[vel], EBf=E @ Bf[vel])
            self._disc = {key: {k: (np.ascontiguousarray(v) if isinstance(v, np.ndarray) else v)
                                for k, v in mats.items()}}
        return self._disc[key]

    # -- run --------------------------------------------------------------------------------------
    def run(self, speed: float, track, irregularity=None, t_end: float = 10.0, *, s0: float | None = None,
            x0: np.ndarray | None = None, abort_states=None, abort_limit: float | None = None) -> VehicleRun:
        """Run at constant ``speed`` [m/s] over ``track`` (:class:`campaign.track.Track`) with the
        lateral ``irregularity`` (callable s [m] -> alignment [m], or None) for ``t_end`` [s], the
        carbody centre at ``s0 + V t`` [m] (default: rear wheelset at s = 0).

        ``x0``: initial mechanical state (28,) (default: centred on the track at rest relative to it);
        ``abort_states``/``abort_limit`` [m or rad]: stop once any of these state indices exceeds the
        limit in magnitude (an unstable run), with ``completed = False``. Raises
        ``tuner.identification.runner.SimulationError`` naming the damper, step and time if an FMU fails.
        """
        if not (math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be finite and > 0 m/s, got {speed}")
        if not (math.isfinite(t_end) and t_end >= self.step):
            raise ValueError(f"t_end must be >= the communication step {self.step} s, got {t_end}")
        if s0 is None:
            s0 = self.params.half_bogie_distance + self.params.semi_wheelbase
        M = self._matrices(speed)
        model = M["model"]
        h, nx, nd = self.step, N_MECH, N_DAMPERS
        n = int(round(t_end / h))
        t = np.arange(n + 1) * h
        U = model.inputs(track, irregularity, s0, t)
        forced = np.ascontiguousarray(U[:-1] @ M["G1u"].T + U[1:] @ M["G2u"].T)
        accU = np.ascontiguousarray(U @ M["EBu"].T)
        X = np.zeros((n + 1, nx))
        F = np.zeros((n + 1, nd))
        X[0] = model.initial_state(track, s0)[:nx] if x0 is None else np.asarray(x0, dtype=float)
        if X[0].shape != (nx,) or not np.all(np.isfinite(X[0])):
            raise ValueError(f"x0 must be {nx} finite values")
        e0, v0 = M["Ex"] @ X[0], M["Ev"] @ X[0]
        for i, d in enumerate(self.dampers):
            F[0, i] = d.start(0.0, float(e0[i]), float(v0[i]))
        idx = np.asarray([] if abort_states is None else abort_states, dtype=np.intc)
        limit = math.inf if abort_limit is None else float(abort_limit)
        if self._loop is not None:
            done = self._run_c(M, n, forced, accU, X, F, idx, limit)
        else:
            done = self._run_py(M, n, forced, accU, X, F, idx, limit)
        k = done + 1
        return VehicleRun(t[:k], X[:k], F[:k], U[:k], model, track, float(s0), completed=done == n)

    def _fail(self, status: int, step: int, damper: int):
        d = self.dampers[damper]
        d.runner._check(status, f"damper {d.name}, step {step} (t = {step * self.step:.6g} s)")
        raise RuntimeError(f"damper {d.name}: FMI status {status} at step {step}")  # pragma: no cover

    def _run_c(self, M, n, forced, accU, X, F, idx, limit) -> int:
        nd = N_DAMPERS
        vp = ctypes.c_void_p * nd
        sr = vp(*[d.fn[0] for d in self.dampers])
        ds = vp(*[d.fn[1] for d in self.dampers])
        gr = vp(*[d.fn[2] for d in self.dampers])
        sd = vp(*[d.der_ptr for d in self.dampers])
        comp = vp(*[d.runner._component for d in self.dampers])
        vr = (ctypes.c_uint * (3 * nd))(*[v for d in self.dampers for v in d.vr])
        dp = ctypes.POINTER(ctypes.c_double)
        ptr = lambda a: a.ctypes.data_as(dp)  # noqa: E731
        done, fstep, fdamp = ctypes.c_int(0), ctypes.c_int(0), ctypes.c_int(0)
        idx = np.ascontiguousarray(idx, dtype=np.intc)
        st = self._loop(n, N_MECH, nd, ptr(M["Phi"]), ptr(forced), ptr(M["G1f"]), ptr(M["G2f"]), ptr(M["Ex"]),
                        ptr(M["Ev"]), ptr(M["Ea"]), ptr(accU), ptr(M["EBf"]), 0.0, self.step, sr, sd, ds, gr, comp,
                        vr, ptr(X), ptr(F), idx.ctypes.data_as(ctypes.POINTER(ctypes.c_int)), int(idx.size),
                        limit if math.isfinite(limit) else 1e300, ctypes.byref(done), ctypes.byref(fstep),
                        ctypes.byref(fdamp))
        if st == 3:
            raise ValueError("vehicle too large for the C master loop")
        if st > 1:
            self._fail(st, fstep.value, fdamp.value)
        return done.value

    def _run_py(self, M, n, forced, accU, X, F, idx, limit) -> int:
        """The C loop's arithmetic and FMI calls, from Python (no C compiler)."""
        h = self.step
        Phi, G1f, G2f, Ex, Ev, Ea, EBf = (M[k] for k in ("Phi", "G1f", "G2f", "Ex", "Ev", "Ea", "EBf"))
        calls = []
        for d in self.dampers:
            r = d.runner
            calls.append((r._set_real, r._do_step, r._get_real, d.set_der, r._component,
                          (ctypes.c_uint * 2)(d.vr[0], d.vr[1]), (ctypes.c_uint * 1)(d.vr[1]),
                          (ctypes.c_uint * 1)(d.vr[2])))
        inp, acc, out = (ctypes.c_double * 2)(), (ctypes.c_double * 1)(), (ctypes.c_double * 1)()
        order = (ctypes.c_int * 1)(1)
        for k in range(n):
            x = X[k]
            e, v = Ex @ x, Ev @ x
            a = Ea @ x + accU[k] + EBf @ F[k]
            for i, (sr, ds, gr, sd, c, vr_in, vr_v, vr_f) in enumerate(calls):
                inp[0], inp[1] = e[i], v[i]
                acc[0] = a[i]
                st = sr(c, vr_in, 2, inp)
                if st <= 1 and sd is not None:
                    st = sd(c, vr_v, 1, order, acc)
                if st <= 1:
                    st = ds(c, k * h, h, 1)
                if st <= 1:
                    st = gr(c, vr_f, 1, out)
                if st > 1:
                    self._fail(st, k, i)
                F[k + 1, i] = out[0]
            X[k + 1] = Phi @ x + forced[k] + G1f @ F[k] + G2f @ F[k + 1]
            if idx.size and not np.all(np.abs(X[k + 1, idx]) <= limit):
                return k + 1
        return n


def reference_run(params: VehicleParams, speed: float, track, irregularity=None, t_end: float = 10.0, *,
                  step: float = DEFAULT_STEP, s0: float | None = None, x0: np.ndarray | None = None) -> VehicleRun:
    """The same run with the built-in Maxwell yaw dampers of :mod:`campaign.vehicle` (the independent
    reference), integrated at ``<= DT_MAX`` and returned on the grid ``k * step`` [s]."""
    if s0 is None:
        s0 = params.half_bogie_distance + params.semi_wheelbase
    model = VehicleModel(params, speed)
    sub = max(1, math.ceil(step / DT_MAX - 1e-9))
    n = int(round(t_end / step))
    tf = np.arange(n * sub + 1) * (step / sub)
    Uf = model.inputs(track, irregularity, s0, tf)
    xi = model.initial_state(track, s0)
    if x0 is not None:
        xi[:N_MECH] = x0
    Xf = model.simulate(tf, Uf, xi)[::sub]
    return VehicleRun(tf[::sub], np.ascontiguousarray(Xf[:, :N_MECH]), np.ascontiguousarray(Xf[:, N_MECH:]),
                      Uf[::sub], model, track, float(s0))


def rk4_linear_forces(rhs, x: np.ndarray, F0, F1, h: float, n: int, dx0: np.ndarray) -> np.ndarray:
    """``n`` classical Runge-Kutta steps of the states ``x`` over ``h`` [s] with the damper forces linear from
    ``F0`` to ``F1`` [N] over the step (each stage sees the force at its own time; both None: no forces put
    in, ``rhs`` gets None); ``rhs(x, F)`` the state derivative, ``dx0`` the derivative at the start (already
    computed). The co-simulation masters' one integration of a car between communication points
    (``nonlinear_cosim``, ``cooperrider_cosim``)."""
    hs = h / n
    dF = None if F0 is None else (F1 - F0) / h

    def force(tau):
        return None if F0 is None else F0 + dF * tau

    for j in range(n):
        tau = j * hs
        k1 = dx0 if j == 0 else rhs(x, force(tau))
        fm = force(tau + 0.5 * hs)
        k2 = rhs(x + 0.5 * hs * k1, fm)
        k3 = rhs(x + 0.5 * hs * k2, fm)
        k4 = rhs(x + hs * k3, force(tau + hs))
        x = x + (hs / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
    return x
