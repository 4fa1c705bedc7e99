"""Physically based twin-tube yaw damper for the virtual rig (the "real" damper).

This is deliberately NOT the lumped model that the tuner identifies (paper section 2.1);
it is a hydraulic model with the usual twin-tube parts, so that the identification
meets a realistic model-form gap.

Layout (x = piston position relative to mid-stroke, positive in extension)::

    actuator s(t) --[mount A: km, cm, optional free play]-- load cell side
        rod + piston (m_rod) ==|== cylinder body (m_body) --[mount B: km, cm]-- frame
    rebound chamber R (annulus A_a = A_p - A_r, volume V_R0 - A_a x)
    compression chamber C (piston area A_p, volume V_C0 + A_p x)
    piston valve  R <-> C : bleed (laminar + turbulent) || rebound blow-off || intake check C->R
    foot valve    C <-> reservoir : bleed || compression blow-off || intake check res->C
    reservoir: oil under a gas cushion, p_res = p_g0 (V_g0 / (V_g0 - dV))^n_gas

Tension force of the cylinder on the rod: ``T_h = p_R A_a - p_C A_p + p_atm A_r + F_f``.
The load cell is in line with the actuator (MTS-style), so it reads the tension of
mount A: ``F = km e(s - x_rod) + cm chi (s' - v_rod)`` (``e``, ``chi``: dead band of the
optional free play). The static reservoir gas force ``-(p_g0 - p_atm) A_r`` is
tared by the rig (see ``campaign.rig``).

Chamber oil with entrained air (volume fraction ``air_fraction`` at ``p_atm``,
polytropic index ``n_air``) gives the pressure-dependent effective bulk modulus
``1/beta_e(p) = (1 - a(p))/beta_l + a(p)/(n_air p)``; ``beta_l`` includes the pressure
tube wall compliance. Chamber pressures follow ``dp/dt = beta_e(p)/V (inflow - dV/dt)``.

Design choices (defaults, SI):

* rod/piston area ratio 2/3 (piston 75 mm, rod 61.2 mm), so that the rebound stiffness
  ``beta A_a^2/V_R`` equals the compression stiffness ``beta A_r^2/(V_R + V_C)`` (in
  compression the intake check couples C and R) and the damper is symmetric, as the
  paper's identified yaw damper is; chambers 90 mm long at mid-stroke, +-80 mm travel;
* foot valve derived from the piston valve with ``Q_f(dp) = r Q_p(r dp)`` (``r = A_r/A_a
  = 2``), so that the compression force equals the rebound force at the same speed;
* piston valve fitted to the paper's Fc table (Table 2): ~2.3 kN at 2.5 mm/s, ~12 kN at
  10 mm/s, ~20 kN at 30 mm/s, ~25 kN at 100 mm/s (blow-off knee at ~1-2 cm/s);
* rubber mounts 6e7 N/m each (loss factor ~0.1 at 10 Hz); with the trapped oil
  (``beta A_a^2/V_R`` ~ 2.3e7 N/m at 10 MPa) the series stiffness is ~1.3e7 N/m for
  strokes that vent one chamber through a check valve and rises towards the sealed-chamber
  value ~2.3e7 N/m for small fast strokes (``series_stiffness``);
* entrained air 0.1 % by volume at p_atm (a well-bled damper): soft oil at low pressure
  (beta_e ~ 0.35e9 Pa at 0.2 MPa, 1.3e9 at 1 MPa, 1.5e9 at 10 MPa), a little compression lag;
* reservoir gas 0.2 MPa absolute (static rod force 291 N, tared by the rig), 1 l of gas.

Two optional model *forms* (``DamperConfig``; off by default, ``campaign.effects.FORMS``), physics of
the rig's own, not the tuner's equations:

* pre-yield hysteresis (MR fluid / seal stiction): a Bouc-Wen element between rod and cylinder, where
  the friction acts, on the piston velocity ``xd = v_rod - v_body``: tension ``F_y zeta`` added to
  ``T_h``, ``zeta' = (xd / x_y) (1 - |zeta|^n (gamma sign(xd zeta) + beta))`` with gamma = beta = 0.5,
  n = 2 (``BW_*``): after a reversal zeta moves linearly from -1 to 0 over x_y, then as tanh towards
  +-1, so the loop dissipates ``~4 F_y A`` per cycle of amplitude ``A >> x_y``. The rhs is continuous
  (its derivative jumps at xd = 0, as for any hysteresis model), so LSODA needs no smoothed sign. Its
  state is integrated only when ``F_y > 0``; its power ``F_y zeta xd`` heats the oil like the friction's;
* bypass groove: a turbulent orifice R -> C in parallel with the piston valve, open where the piston
  passes a groove in the pressure tube: ``Q = Cd A_g g(x) sqrt(2 |dp| / rho) sign(dp)`` (regularised
  at dp -> 0 like the blow-off flow; Cd of the piston valve; not temperature scaled: a sharp-edged
  orifice), ``g(x) = (tanh((x - x0 + w/2) / e) - tanh((x - x0 - w/2) / e)) / 2``. It lowers the
  rebound force inside the groove (defaults: -43 % at 5 mm/s, -2.6 % at 30 mm/s once the blow-off
  valve is open); the compression force is set by the foot valve and hardly changes.

The system is stiff (microsecond modes from oil compressibility, mounts and rod mass):
it is integrated with LSODA (scipy ``odeint``: BDF when stiff) and an analytic
Jacobian; the stroke enters through a cubic spline of the input samples.
"""
from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import odeint
from scipy.interpolate import CubicSpline

P_ATM = 101325.0  # Pa


@dataclass(frozen=True)
class ValveSet:
    """One valve assembly between two volumes; positive pressure drop ``dp`` drives the
    damping ("forward") flow.

    bleed: laminar + turbulent orifice in series, ``dp = R_l Q + R_t Q|Q|``
    (``R_l`` [Pa s/m^3], ``R_t = rho / (2 Cd^2 A_o^2)`` from ``orifice_area`` [m^2]);
    blow-off (forward only): spring-loaded disc, opening 0 below ``blowoff_crack`` [Pa],
    linear up to full lift at ``blowoff_full`` [Pa], flow area at full lift
    ``blowoff_area`` [m^2], ``Q = Cd A sqrt(2 dp / rho)``;
    check (reverse only): same law with ``check_crack``, ``check_full`` [Pa], ``check_area`` [m^2].
    Opening corners are rounded with softplus of width ``smooth_blowoff`` / ``smooth_check`` [Pa].
    """

    laminar_resistance: float
    orifice_area: float
    blowoff_crack: float
    blowoff_full: float
    blowoff_area: float
    check_crack: float = 20e3
    check_full: float = 80e3
    check_area: float = 30e-6
    discharge_coefficient: float = 0.7
    smooth_blowoff: float = 0.25e6
    smooth_check: float = 5e3

    def scaled(self, r: float) -> "ValveSet":
        """Valve with ``Q'(dp) = r Q(r dp)``: carries r times the flow at 1/r times the
        pressure drop, so that ``dp' A' = dp A`` when ``A' = r A`` (used for the foot valve)."""
        return replace(
            self, laminar_resistance=self.laminar_resistance / r**2,
            orifice_area=self.orifice_area * r**1.5,
            blowoff_crack=self.blowoff_crack / r, blowoff_full=self.blowoff_full / r,
            blowoff_area=self.blowoff_area * r**1.5, check_crack=self.check_crack / r,
            check_full=self.check_full / r, check_area=self.check_area * r**1.5,
            smooth_blowoff=self.smooth_blowoff / r, smooth_check=self.smooth_check / r)


# Fitted (least squares on log force, quasi_static_force) to the paper's Table 2 Fc
# ordinates at 2.5-100 mm/s with the full-lift pressure fixed above the operating range.
PISTON_VALVE = ValveSet(
    laminar_resistance=3.9e11,  # Pa s/m^3: spool clearance leakage (viscous)
    orifice_area=0.27e-6,  # m^2: bleed orifice, ~0.59 mm diameter
    blowoff_crack=11.7e6,  # Pa: spring preload / seat area
    blowoff_full=22.0e6,  # Pa: full lift (above the operating range)
    blowoff_area=1.67e-6,  # m^2: ~10.6 mm spool port opened 0.05 mm
)


@dataclass(frozen=True)
class DamperParams:
    """Physical parameters of the rig damper (SI units; temperatures in degC)."""

    piston_diameter: float = 0.075  # m
    rod_diameter: float = 0.06124  # m  (A_r / A_p = 2/3)
    rebound_length: float = 0.09  # m, rebound chamber length at mid-stroke
    compression_length: float = 0.09  # m, compression chamber length at mid-stroke
    dead_volume: float = 10e-6  # m^3, valve galleries per chamber
    travel: float = 0.08  # m, +- piston travel from mid-stroke
    oil_density: float = 870.0  # kg/m^3
    bulk_modulus: float = 1.55e9  # Pa, oil 1.8e9 with pressure-tube wall compliance
    air_fraction: float = 0.001  # entrained free air volume fraction at p_atm (well bled)
    n_air: float = 1.4  # polytropic index of the air bubbles
    gas_pressure: float = 0.2e6  # Pa absolute, reservoir gas at mid-stroke
    gas_volume: float = 1.0e-3  # m^3, reservoir gas at mid-stroke
    n_gas: float = 1.0  # polytropic index of the reservoir gas
    piston_valve: ValveSet = PISTON_VALVE
    foot_valve: ValveSet | None = None  # None: PISTON_VALVE.scaled(A_r / A_a)
    mount_stiffness: float = 6.0e7  # N/m, each rubber end mount
    mount_damping: float = 1.0e5  # N s/m, each mount (loss factor ~0.1 at 10 Hz)
    rod_mass: float = 6.0  # kg, rod + piston + eye
    body_mass: float = 20.0  # kg, tubes + oil + eye
    heat_capacity: float = 4000.0  # J/K, oil + inner tube
    heat_transfer: float = 5.0  # W/K, to ambient
    ambient_temperature: float = 20.0  # degC, also the oil temperature at the start of a test
    viscosity_reference_temperature: float = 20.0  # degC, where the valve characteristics apply as given

    @property
    def area_piston(self) -> float:
        return math.pi / 4 * self.piston_diameter**2

    @property
    def area_rod(self) -> float:
        return math.pi / 4 * self.rod_diameter**2

    @property
    def area_annulus(self) -> float:
        return self.area_piston - self.area_rod

    @property
    def foot(self) -> ValveSet:
        if self.foot_valve is not None:
            return self.foot_valve
        return self.piston_valve.scaled(self.area_rod / self.area_annulus)

    @property
    def static_gas_force(self) -> float:
        """Tension [N] of the cylinder on the rod at rest at mid-stroke (negative: the gas
        pushes the rod out, so the load cell sees compression)."""
        return -(self.gas_pressure - P_ATM) * self.area_rod


@dataclass(frozen=True)
class DamperConfig:
    """Effect switches acting inside the damper physics (0 = off).

    friction_force [N] (Coulomb, ``Ff tanh(v / friction_v_eps)``, v_eps [m/s]),
    free_play [m] (total dead band width in mount A), thermal_beta [1/K] (valve pressure
    drops scaled by ``exp(-beta (T - T_ref))``, thermal balance on), valve_tau [s]
    (first-order lag of the blow-off valve openings), extra_mass [kg] (equivalent
    fluid/rod inertia added to the rod).

    Two model *forms* beyond the catalogue (see the module docstring for their laws):
    preyield_force [N] (``F_y`` of a Bouc-Wen pre-yield hysteresis element between rod and
    cylinder, ``preyield_displacement`` [m]: its yield displacement ``x_y``); bypass_area [m^2]
    (``A_g`` of a bypass groove R <-> C open around ``bypass_center`` [m] over ``bypass_length`` [m]
    with edges ``bypass_edge`` [m] long)."""

    friction_force: float = 0.0
    friction_v_eps: float = 0.5e-3
    free_play: float = 0.0
    thermal_beta: float = 0.0
    valve_tau: float = 0.0
    extra_mass: float = 0.0
    free_play_smoothing: float = 2e-6  # m
    preyield_force: float = 0.0
    preyield_displacement: float = 0.5e-3  # m
    bypass_area: float = 0.0
    bypass_center: float = 0.0  # m
    bypass_length: float = 10e-3  # m
    bypass_edge: float = 1e-3  # m

    @property
    def preyield(self) -> bool:
        """The Bouc-Wen element is on (its state ``zeta`` is integrated)."""
        return self.preyield_force > 0.0

    def bypass_window(self, x: float) -> tuple[float, float]:
        """Groove opening g(x) in [0, 1] at piston position x [m] and dg/dx [1/m]."""
        e, h = self.bypass_edge, 0.5 * self.bypass_length
        t1 = math.tanh((x - self.bypass_center + h) / e)
        t2 = math.tanh((x - self.bypass_center - h) / e)
        return 0.5 * (t1 - t2), 0.5 * (t2 * t2 - t1 * t1) / e


# ---------------------------------------------------------------- scalar helpers
def _softplus(z: float, w: float) -> float:
    return max(z, 0.0) + w * math.log1p(math.exp(-abs(z) / w))


def _sigmoid(z: float) -> float:
    if z >= 0:
        return 1.0 / (1.0 + math.exp(-z))
    e = math.exp(z)
    return e / (1.0 + e)


def _opening(u: float, crack: float, full: float, w: float) -> tuple[float, float]:
    """Quasi-static normalised opening in [0, 1] at pressure drop u and its derivative."""
    span = full - crack
    y = (_softplus(u - crack, w) - _softplus(u - full, w)) / span
    dy = (_sigmoid((u - crack) / w) - _sigmoid((u - full) / w)) / span
    return y, dy


_P_TURB = 1e3  # Pa, regularisation of sqrt(dp) at dp -> 0


def _turb(u: float, k: float) -> tuple[float, float]:
    """Q = k u / (u^2 + pt^2)^(1/4) (~ k sqrt|u| sign u) and dQ/du."""
    s = u * u + _P_TURB * _P_TURB
    r = s**-0.25
    return k * u * r, k * (0.5 * u * u + _P_TURB * _P_TURB) * r / s


def valve_flow(vs: ValveSet, dp: float, phi: float, rho: float, y_dyn: float | None):
    """Flow [m^3/s] through a valve set at pressure drop dp [Pa].

    phi scales the damping pressure drops (bleed, blow-off): ``Q = Q0(dp / phi)``;
    y_dyn is the blow-off opening state (None: quasi-static). Returns
    (Q, dQ/d(dp), dQ/d(phi), dQ/d(y_dyn)), the last 0 when quasi-static.
    """
    kc = vs.discharge_coefficient * math.sqrt(2.0 / rho)
    u = dp / phi
    # bleed: u = R_l Q + R_t Q|Q|
    rl = vs.laminar_resistance
    rt = rho / (2.0 * (vs.discharge_coefficient * vs.orifice_area) ** 2)
    qb = 2.0 * u / (rl + math.sqrt(rl * rl + 4.0 * rt * abs(u)))
    dqb = 1.0 / (rl + 2.0 * rt * abs(qb))
    # blow-off
    yq, dyq = _opening(u, vs.blowoff_crack, vs.blowoff_full, vs.smooth_blowoff)
    qt, dqt = _turb(u, kc)
    if y_dyn is None:
        y = yq
        qbo = vs.blowoff_area * y * qt
        dqbo_du = vs.blowoff_area * (y * dqt + dyq * qt)
        dq_dy = 0.0
    else:
        y = y_dyn
        qbo = vs.blowoff_area * y * qt
        dqbo_du = vs.blowoff_area * y * dqt
        dq_dy = vs.blowoff_area * qt
    # reverse check valve (not temperature scaled)
    yc, dyc = _opening(-dp, vs.check_crack, vs.check_full, vs.smooth_check)
    qc, dqc = _turb(-dp, kc)
    qchk = -vs.check_area * yc * qc
    dqchk = vs.check_area * (yc * dqc + dyc * qc)
    dq_du = dqb + dqbo_du
    q = qb + qbo + qchk
    return q, dq_du / phi + dqchk, -dq_du * u / phi, dq_dy


def bulk_modulus(p: float, par: DamperParams) -> tuple[float, float]:
    """Effective bulk modulus [Pa] of oil with entrained air at absolute pressure p [Pa],
    and its derivative d beta / dp."""
    p = max(p, 1e3)
    a0, n = par.air_fraction, par.n_air
    uu = a0 * (P_ATM / p) ** (1.0 / n)
    den = uu + 1.0 - a0
    a = uu / den
    da = (1.0 - a0) / den**2 * (-uu / (n * p))
    g = (1.0 - a) / par.bulk_modulus + a / (n * p)
    dg = -da / par.bulk_modulus + da / (n * p) - a / (n * p * p)
    return 1.0 / g, -dg / (g * g)


def quasi_static_force(v: float, par: DamperParams, bypass_area: float = 0.0) -> float:
    """Steady damping force [N] (tension +, gas force tared) at constant piston speed
    v [m/s], incompressible, from the valve laws alone: an independent reference for
    the dynamic simulation's slow-speed force-velocity curve. bypass_area [m^2]: a fully
    open bypass groove (``DamperConfig.bypass_area`` with the piston inside the groove)
    in parallel with the piston valve."""
    from scipy.optimize import brentq

    aa, ar, rho = par.area_annulus, par.area_rod, par.oil_density
    foot = par.foot
    kc = par.piston_valve.discharge_coefficient * math.sqrt(2.0 / rho)

    def dp_for(vs, q):
        if q == 0.0:
            return 0.0
        extra = bypass_area if vs is par.piston_valve else 0.0
        f = lambda d: valve_flow(vs, d, 1.0, rho, None)[0] + extra * _turb(d, kc)[0] - q  # noqa: E731
        lo, hi = (0.0, 1e6) if q > 0 else (-1e6, 0.0)
        while f(hi) < 0:
            hi *= 2
        while f(lo) > 0:
            lo *= 2
        return brentq(f, lo, hi, xtol=1e-6, rtol=1e-12)

    if v >= 0:  # rebound: R -> C through the piston valve, res -> C through the foot check
        dpp = dp_for(par.piston_valve, aa * v)
        dpf = dp_for(foot, -ar * v)  # negative: p_C below p_res
        # p_C = p_res + dpf, p_R = p_C + dpp; T_h - T_h0 = dpp A_a + dpf (A_a - A_p)
        return dpp * aa - dpf * ar
    dpf = dp_for(foot, -ar * v)  # C -> res through the foot valve (positive)
    dpp = dp_for(par.piston_valve, aa * v)  # C -> R through the piston check (negative)
    return dpp * aa - dpf * ar


def series_stiffness(par: DamperParams, pressure: float) -> dict[str, float]:
    """Static series stiffness [N/m] at mid-stroke with the chamber oil at absolute
    pressure [Pa] (bulk modulus ``beta_e(pressure)``), two mounts in series with the oil:

    ``rebound``: R compressed, C vented to the reservoir by the intake check;
    ``compression``: C and R compressed together through the piston check;
    ``sealed``: both chambers trapped (no valve flow; the high-frequency, small-amplitude
    limit), ``beta (A_a^2/V_R + A_p^2/V_C)``.
    """
    beta, _ = bulk_modulus(pressure, par)
    vr = par.area_annulus * par.rebound_length + par.dead_volume
    vc = par.area_piston * par.compression_length + par.dead_volume
    hyd = {"rebound": beta * par.area_annulus**2 / vr,
           "compression": beta * par.area_rod**2 / (vr + vc),
           "sealed": beta * (par.area_annulus**2 / vr + par.area_piston**2 / vc)}
    km = par.mount_stiffness
    return {k: 1.0 / (2.0 / km + 1.0 / v) for k, v in hyd.items()}


# ---------------------------------------------------------------- stroke input
class StrokeInput:
    """Smooth interpolant of the imposed stroke: cubic spline through (t [s], s [m])."""

    def __init__(self, t: np.ndarray, s: np.ndarray):
        self.spline = CubicSpline(t, s)
        self.t = t
        self._bp = t.tolist()
        self._c = self.spline.c.T.tolist()  # per interval: [c3, c2, c1, c0]
        self._n = len(self._bp) - 2
        self._s0, self._v0 = float(s[0]), float(self.spline(t[0], 1))
        self._s1, self._v1 = float(s[-1]), float(self.spline(t[-1], 1))

    def eval(self, tt: float) -> tuple[float, float]:
        """s [m], s' [m/s] at a scalar time (linear extrapolation outside the range)."""
        bp = self._bp
        if tt <= bp[0]:
            return self._s0 + self._v0 * (tt - bp[0]), self._v0
        if tt >= bp[-1]:
            return self._s1 + self._v1 * (tt - bp[-1]), self._v1
        i = min(bisect_right(bp, tt) - 1, self._n)
        h = tt - bp[i]
        c3, c2, c1, c0 = self._c[i]
        return ((c3 * h + c2) * h + c1) * h + c0, (3.0 * c3 * h + 2.0 * c2) * h + c1

    def __call__(self, tt, nu: int = 0):
        tt = np.clip(np.asarray(tt, dtype=float), self.t[0], self.t[-1])
        return self.spline(tt, nu)


# ---------------------------------------------------------------- the model
N_STATES = 11
# d_a = s - x_rod (mount A deflection, kept as a state so the force has no cancellation);
# zeta (IZ, the Bouc-Wen state) is last: it is integrated only when the element is on
# (``RigDamper.n_states``), so that a damper without it integrates exactly the 10 states it
# always had and gives the same numbers bit for bit
(ID_A, IV_R, IX_B, IV_B, IP_R, IP_C, IV_RES, IT, IY_P, IY_F, IZ) = range(N_STATES)
#: Bouc-Wen shape: d zeta/dt = (xd / x_y) (1 - |zeta|^n (gamma sign(xd zeta) + beta))
BW_GAMMA, BW_BETA, BW_N = 0.5, 0.5, 2
#: LSODA absolute tolerance per state, times rtol
ATOL_SCALE = np.array([1e-2, 1.0, 1e-2, 1.0, 1e8, 1e8, 1e-2, 10.0, 1e2, 1e2, 1.0])


@dataclass
class DamperResponse:
    """Clean (sensor-free) rig damper response on the output grid.

    t [s]; stroke, stroke_velocity, stroke_acceleration: imposed actuator motion [m, m/s,
    m/s^2]; force [N]: load-cell tension with the static gas force tared; tare [N]: the
    subtracted static force; piston [m]: piston position x; p_rebound, p_compression,
    p_reservoir [Pa abs]; temperature [degC]; states: raw state matrix (``N_STATES`` columns,
    zeta = 0 when the Bouc-Wen element is off)."""

    t: np.ndarray
    stroke: np.ndarray
    stroke_velocity: np.ndarray
    stroke_acceleration: np.ndarray
    force: np.ndarray
    tare: float
    piston: np.ndarray
    p_rebound: np.ndarray
    p_compression: np.ndarray
    p_reservoir: np.ndarray
    temperature: np.ndarray
    states: np.ndarray = field(repr=False)


def _valve_constants(vs: ValveSet, rho: float) -> tuple:
    """A valve's constants in the order ``_fast_fluid``'s flow takes them (SI): laminar resistance, turbulent
    coefficient, orifice gain, blow-off crack and full pressure, smoothing and area, check crack and full
    pressure, smoothing and area."""
    cd = vs.discharge_coefficient
    return (vs.laminar_resistance, rho / (2.0 * (cd * vs.orifice_area) ** 2),
            cd * math.sqrt(2.0 / rho), vs.blowoff_crack, vs.blowoff_full,
            vs.smooth_blowoff, vs.blowoff_area, vs.check_crack, vs.check_full,
            vs.smooth_check, vs.check_area)


def _fast_fluid(p: "DamperParams"):
    """(flow, opening, beta_e): the closures over ``p``'s constants that ``RigDamper.fast_rhs`` calls, the same
    sums as ``valve_flow``, ``_opening`` and ``bulk_modulus`` without their partials. flow(constants, dp [Pa],
    phi, y or None) [m^3/s] with ``_valve_constants``; opening(u [Pa], crack, full, w) [0-1]; beta_e(p [Pa]) [Pa]."""
    pt2 = _P_TURB * _P_TURB
    a0, nair, bl = p.air_fraction, p.n_air, p.bulk_modulus
    inv_n = 1.0 / nair
    exp, sqrt, log1p = math.exp, math.sqrt, math.log1p

    def sp(z, w):
        return (z if z > 0 else 0.0) + w * log1p(exp(-abs(z) / w))

    def opening(u, crack, full, w):
        if u < crack - 40.0 * w:
            return 0.0
        return (sp(u - crack, w) - sp(u - full, w)) / (full - crack)

    def flow(cs, dp, phi, ydyn):
        rl, rt, kc, pc, pf, wb, ab, cc, cf, wc, ac = cs
        u = dp / phi
        q = 2.0 * u / (rl + sqrt(rl * rl + 4.0 * rt * abs(u)))
        y = opening(u, pc, pf, wb) if ydyn is None else ydyn
        if y != 0.0:
            q += ab * y * kc * u / (u * u + pt2) ** 0.25
        yc = opening(-dp, cc, cf, wc)
        if yc != 0.0:
            q += ac * yc * kc * dp / (dp * dp + pt2) ** 0.25
        return q

    def beta_e(pp):
        if pp < 1e3:
            pp = 1e3
        uu = a0 * (P_ATM / pp) ** inv_n
        a = uu / (uu + 1.0 - a0)
        return 1.0 / ((1.0 - a) / bl + a / (nair * pp))

    return flow, opening, beta_e


@dataclass(frozen=True)
class _Terms:
    """What the derivative and its Jacobian share at one state (``RigDamper._terms``; SI units): the state, the
    actuator rate, the relative rod rate, mount A's tension and its partials, the friction (with F_y zeta) and
    its rate partial, the Bouc-Wen (d zeta/dt and its partials in the rate and zeta), the rod's thrust, the
    reservoir pressure's partial in the displaced volume, the viscosity factor, the valves' pressure drops, their
    (flow, partials in pressure, viscosity factor and opening) for the piston then the foot valve, the bypass
    flow's partial in the stroke, the chambers' volumes, bulk moduli and net flows, and the lagged openings'
    targets with their partials (piston, foot)."""

    y: np.ndarray
    sd: float
    xd: float
    ta: float
    dta_d: float
    dta_dd: float
    th_f: float
    dthf: float
    bw: tuple
    th: float
    dpres: float
    phi: float
    dpp: float
    dpf: float
    valves: tuple
    dqbp_dx: float
    vR: float
    vC: float
    bR: float
    dbR: float
    bC: float
    dbC: float
    flowR: float
    flowC: float
    yq: tuple


class RigDamper:
    """Twin-tube damper under displacement control; see the module docstring."""

    def __init__(self, params: DamperParams | None = None, config: DamperConfig | None = None):
        self.p = params or DamperParams()
        self.c = config or DamperConfig()
        p, c = self.p, self.c
        for name in ("friction_force", "free_play", "thermal_beta", "valve_tau", "extra_mass",
                     "preyield_force", "bypass_area"):
            v = getattr(c, name)
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"DamperConfig.{name} must be finite and >= 0, got {v}")
        for name in ("preyield_displacement", "bypass_length", "bypass_edge"):
            v = getattr(c, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"DamperConfig.{name} must be finite and > 0, got {v}")
        if not math.isfinite(c.bypass_center):
            raise ValueError(f"DamperConfig.bypass_center must be finite, got {c.bypass_center}")
        #: states integrated: the Bouc-Wen state only when the element is on
        self.n_states = N_STATES if c.preyield else N_STATES - 1
        self.aa, self.ap, self.ar = p.area_annulus, p.area_piston, p.area_rod
        if self.aa <= 0:
            raise ValueError("rod_diameter must be smaller than piston_diameter")
        self.vr0 = self.aa * p.rebound_length + p.dead_volume
        self.vc0 = self.ap * p.compression_length + p.dead_volume
        self.foot = p.foot
        self.m_rod = p.rod_mass + c.extra_mass

    # -------------------------------------------------------------- pieces
    def _mount_a(self, d: float, dd: float):
        """Mount A tension and its partials w.r.t. deflection d and rate dd."""
        k, cm, g = self.p.mount_stiffness, self.p.mount_damping, self.c.free_play
        if g <= 0.0:
            return k * d + cm * dd, k, cm
        w = self.c.free_play_smoothing
        h = 0.5 * g
        e = _softplus(d - h, w) - _softplus(-d - h, w)
        s1, s2 = _sigmoid((d - h) / w), _sigmoid((-d - h) / w)
        de = s1 + s2
        chi = s1 + s2
        dchi = (s1 * (1 - s1) - s2 * (1 - s2)) / w
        return k * e + cm * chi * dd, k * de + cm * dchi * dd, cm * chi

    def _p_res(self, dv: float) -> tuple[float, float]:
        p = self.p
        vg = p.gas_volume - dv
        pr = p.gas_pressure * (p.gas_volume / vg) ** p.n_gas
        return pr, pr * p.n_gas / vg

    def static_state(self, s0: float) -> np.ndarray:
        """Equilibrium state at rest with the actuator at stroke s0 [m] (``n_states`` long; a
        Bouc-Wen element starts virgin, zeta = 0)."""
        p = self.p
        y = np.zeros(self.n_states)
        # the gas force depends on rod position and the deflections on the gas force: iterate
        xb, xr = 0.0, s0
        for _ in range(50):
            x = xr - xb
            dv = -self.ar * x
            pr, _ = self._p_res(dv)
            th = (P_ATM - pr) * self.ar
            xb_new = th / p.mount_stiffness
            d = self._invert_mount(th)
            xr_new = s0 - d
            if abs(xr_new - xr) + abs(xb_new - xb) < 1e-15:
                break
            xr, xb = xr_new, xb_new
        y[ID_A], y[IX_B] = s0 - xr, xb
        y[IP_R] = y[IP_C] = pr
        y[IV_RES] = dv
        y[IT] = p.ambient_temperature
        return y

    def _invert_mount(self, force: float) -> float:
        """Static deflection of mount A carrying ``force`` [N] (Newton on the dead band)."""
        d = force / self.p.mount_stiffness
        if self.c.free_play <= 0:
            return d
        d += math.copysign(0.5 * self.c.free_play, force if force != 0 else 1.0)
        for _ in range(100):
            f, k, _ = self._mount_a(d, 0.0)
            step = (f - force) / k
            d -= step
            if abs(step) < 1e-14:
                break
        return d

    # -------------------------------------------------------------- rhs + Jacobian
    def _eval(self, y, t, stroke: StrokeInput, want_jac: bool):
        """(the state derivative, its Jacobian d f / d y or None): ``_terms`` at the state, then both from them."""
        terms = self._terms(y, t, stroke)
        return self._derivative(terms), (self._jacobian(terms) if want_jac else None)

    def _terms(self, y, t, stroke: StrokeInput) -> "_Terms":
        """The forces, flows and fluid properties at state ``y`` and time ``t`` [s], with their partials."""
        p, c = self.p, self.c
        aa, ap = self.aa, self.ap
        da, vr, xb, vb, pR, pC, dv, temp, yp, yf = y[:IZ]
        s, sd = stroke.eval(t)
        x, xd = s - da - xb, vr - vb
        ta, dta_d, dta_dd = self._mount_a(da, sd - vr)
        ff, veps = c.friction_force, c.friction_v_eps
        th_f = ff * math.tanh(xd / veps) if ff > 0 else 0.0
        dthf = ff / veps * (1.0 - (th_f / ff) ** 2) if ff > 0 else 0.0
        bw = (0.0, 0.0, 0.0)
        if c.preyield:  # Bouc-Wen: force F_y zeta, acting like the friction
            z, xy = y[IZ], c.preyield_displacement
            zn = abs(z) ** BW_N
            shape = BW_GAMMA * (1.0 if xd * z >= 0.0 else -1.0) + BW_BETA
            bw = (xd / xy * (1.0 - zn * shape), (1.0 - zn * shape) / xy,
                  -xd / xy * BW_N * abs(z) ** (BW_N - 1) * math.copysign(1.0, z) * shape)
            th_f += c.preyield_force * z
        pres, dpres = self._p_res(dv)
        beta = c.thermal_beta
        phi = math.exp(-beta * (temp - p.viscosity_reference_temperature)) if beta > 0 else 1.0
        lag = c.valve_tau > 0
        dpp, dpf = pR - pC, pC - pres
        qp, gp, hp, jp = valve_flow(p.piston_valve, dpp, phi, p.oil_density, yp if lag else None)
        qf, gf, hf, jf = valve_flow(self.foot, dpf, phi, p.oil_density, yf if lag else None)
        dqbp_dx = 0.0
        if c.bypass_area > 0:  # bypass groove R -> C, in parallel with the piston valve
            g, dg = c.bypass_window(x)
            kc = p.piston_valve.discharge_coefficient * math.sqrt(2.0 / p.oil_density)
            qt, dqt = _turb(dpp, kc)
            qp += c.bypass_area * g * qt
            gp += c.bypass_area * g * dqt
            dqbp_dx = c.bypass_area * dg * qt
        vR, vC = self.vr0 - aa * x, self.vc0 + ap * x
        bR, dbR = bulk_modulus(pR, p)
        bC, dbC = bulk_modulus(pC, p)
        yq = (0.0, 0.0, 0.0, 0.0)
        if lag:
            vp, vf = p.piston_valve, self.foot
            yq = (*_opening(dpp / phi, vp.blowoff_crack, vp.blowoff_full, vp.smooth_blowoff),
                  *_opening(dpf / phi, vf.blowoff_crack, vf.blowoff_full, vf.smooth_blowoff))
        return _Terms(y=y, sd=sd, xd=xd, ta=ta, dta_d=dta_d, dta_dd=dta_dd, th_f=th_f, dthf=dthf, bw=bw,
                      th=pR * aa - pC * ap + P_ATM * self.ar + th_f, dpres=dpres, phi=phi, dpp=dpp, dpf=dpf,
                      valves=(qp, gp, hp, jp, qf, gf, hf, jf), dqbp_dx=dqbp_dx, vR=vR, vC=vC, bR=bR, dbR=dbR,
                      bC=bC, dbC=dbC, flowR=aa * xd - qp, flowC=-ap * xd + qp - qf, yq=yq)

    def _derivative(self, tm: "_Terms") -> list[float]:
        """The state derivative from the ``_terms`` at a state."""
        p, c = self.p, self.c
        qp, _, _, _, qf, _, _, _ = tm.valves
        f = [0.0] * self.n_states
        f[ID_A] = tm.sd - tm.y[IV_R]
        f[IV_R] = (tm.ta - tm.th) / self.m_rod
        f[IX_B] = tm.y[IV_B]
        f[IV_B] = (tm.th - (p.mount_stiffness * tm.y[IX_B] + p.mount_damping * tm.y[IV_B])) / p.body_mass
        f[IP_R] = tm.bR / tm.vR * tm.flowR
        f[IP_C] = tm.bC / tm.vC * tm.flowC
        f[IV_RES] = qf
        if c.preyield:
            f[IZ] = tm.bw[0]
        if c.thermal_beta > 0:
            power = qp * tm.dpp + qf * tm.dpf + tm.th_f * tm.xd
            f[IT] = (power - p.heat_transfer * (tm.y[IT] - p.ambient_temperature)) / p.heat_capacity
        if c.valve_tau > 0:
            f[IY_P] = (tm.yq[0] - tm.y[IY_P]) / c.valve_tau
            f[IY_F] = (tm.yq[2] - tm.y[IY_F]) / c.valve_tau
        return f

    def _jacobian(self, tm: "_Terms") -> np.ndarray:
        """Analytic d f / d y from the ``_terms`` at a state: the rod, the body and the two chambers here, the
        thermal and valve-lag rows in ``_jacobian_extras``."""
        p, c = self.p, self.c
        aa, ap = self.aa, self.ap
        k, cm = p.mount_stiffness, p.mount_damping
        qp, gp, hp, jp, qf, gf, hf, jf = tm.valves
        dthf, dqbp_dx, dpres, flowR, flowC, vR, vC = tm.dthf, tm.dqbp_dx, tm.dpres, tm.flowR, tm.flowC, tm.vR, tm.vC
        n = self.n_states
        J = np.zeros((n, n))
        J[ID_A, IV_R] = -1.0
        J[IX_B, IV_B] = 1.0
        # th partials: pR: aa, pC: -ap, xd: dthf (vr +, vb -)
        mr, mb = self.m_rod, p.body_mass
        J[IV_R, ID_A] = tm.dta_d / mr
        J[IV_R, IV_R] = (-tm.dta_dd - dthf) / mr
        J[IV_R, IV_B] = dthf / mr
        J[IV_R, IP_R] = -aa / mr
        J[IV_R, IP_C] = ap / mr
        J[IV_B, IX_B] = -k / mb
        J[IV_B, IV_R] = dthf / mb
        J[IV_B, IV_B] = (-dthf - cm) / mb
        J[IV_B, IP_R] = aa / mb
        J[IV_B, IP_C] = -ap / mb
        if c.preyield:
            fy, (_, dz_dxd, dz_dz) = c.preyield_force, tm.bw
            J[IV_R, IZ] = -fy / mr
            J[IV_B, IZ] = fy / mb
            J[IZ, IV_R] = dz_dxd
            J[IZ, IV_B] = -dz_dxd
            J[IZ, IZ] = dz_dz
        # dphi/dT
        dphi = -c.thermal_beta * tm.phi
        # rebound chamber: f = bR/vR * flowR
        cR = tm.bR / vR
        # x = s - d_a - x_b; d(1/vR)/dx = aa/vR^2, d(1/vC)/dx = -ap/vC^2
        # (the bypass flow depends on x too: d qbp / d d_a = d qbp / d x_b = -dqbp_dx)
        J[IP_R, ID_A] = J[IP_R, IX_B] = -cR * flowR * aa / vR + cR * dqbp_dx
        J[IP_R, IV_R] = cR * aa
        J[IP_R, IV_B] = -cR * aa
        J[IP_R, IP_R] = tm.dbR / vR * flowR - cR * gp
        J[IP_R, IP_C] = cR * gp
        J[IP_R, IT] = -cR * hp * dphi
        J[IP_R, IY_P] = -cR * jp
        cC = tm.bC / vC
        J[IP_C, ID_A] = J[IP_C, IX_B] = cC * flowC * ap / vC - cC * dqbp_dx
        J[IP_C, IV_R] = -cC * ap
        J[IP_C, IV_B] = cC * ap
        J[IP_C, IP_R] = cC * gp
        J[IP_C, IP_C] = tm.dbC / vC * flowC + cC * (-gp - gf)
        J[IP_C, IV_RES] = cC * gf * dpres
        J[IP_C, IT] = cC * (hp - hf) * dphi
        J[IP_C, IY_P] = cC * jp
        J[IP_C, IY_F] = -cC * jf
        J[IV_RES, IP_C] = gf
        J[IV_RES, IV_RES] = -gf * dpres
        J[IV_RES, IT] = hf * dphi
        J[IV_RES, IY_F] = jf
        self._jacobian_extras(J, tm, dphi)
        return J

    def _jacobian_extras(self, J: np.ndarray, tm: "_Terms", dphi: float) -> None:
        """The thermal and valve-lag rows of ``_jacobian`` (``dphi``: d phi / d T [1/K]), into ``J``."""
        p, c = self.p, self.c
        qp, gp, hp, jp, qf, gf, hf, jf = tm.valves
        dpp, dpf, dpres, phi = tm.dpp, tm.dpf, tm.dpres, tm.phi
        if c.thermal_beta > 0:
            hc = p.heat_capacity
            # power = qp dpp + qf dpf + th_f xd (qp with the bypass, th_f with F_y zeta)
            dP_dpp = qp + dpp * gp
            dP_dpf = qf + dpf * gf
            dP_dxd = tm.th_f + tm.dthf * tm.xd
            J[IT, ID_A] = J[IT, IX_B] = -dpp * tm.dqbp_dx / hc
            if c.preyield:
                J[IT, IZ] = c.preyield_force * tm.xd / hc
            J[IT, IP_R] = dP_dpp / hc
            J[IT, IP_C] = (-dP_dpp + dP_dpf) / hc
            J[IT, IV_RES] = -dP_dpf * dpres / hc
            J[IT, IV_R] = dP_dxd / hc
            J[IT, IV_B] = -dP_dxd / hc
            J[IT, IT] = ((dpp * hp + dpf * hf) * dphi - p.heat_transfer) / hc
            J[IT, IY_P] = dpp * jp / hc
            J[IT, IY_F] = dpf * jf / hc
        if c.valve_tau > 0:
            # f = (yq(dp/phi) - y)/tau
            tau, (_, dyqp, _, dyqf) = c.valve_tau, tm.yq
            up, uf = dpp / phi, dpf / phi
            J[IY_P, IP_R] = dyqp / phi / tau
            J[IY_P, IP_C] = -dyqp / phi / tau
            J[IY_P, IT] = -dyqp * up / phi * dphi / tau
            J[IY_P, IY_P] = -1.0 / tau
            J[IY_F, IP_C] = dyqf / phi / tau
            J[IY_F, IV_RES] = -dyqf / phi * dpres / tau
            J[IY_F, IT] = -dyqf * uf / phi * dphi / tau
            J[IY_F, IY_F] = -1.0 / tau

    def rhs(self, y, t, stroke: StrokeInput) -> list[float]:
        """State derivative (LSODA calling convention y, t); reference implementation."""
        return self._eval(y, t, stroke, False)[0]

    def fast_rhs(self, stroke: StrokeInput):
        """Same derivative as ``rhs`` as a closure over local constants, with early exits
        for closed valves and for the forms that are off (the integrator spends most of its
        time here)."""
        p, c = self.p, self.c
        aa, ap, ar = self.aa, self.ap, self.ar
        k, cm, mr, mb = p.mount_stiffness, p.mount_damping, self.m_rod, p.body_mass
        gap = c.free_play
        hgap, wgap = 0.5 * gap, c.free_play_smoothing
        ff, veps = c.friction_force, c.friction_v_eps
        beta, tamb, tref = c.thermal_beta, p.ambient_temperature, p.viscosity_reference_temperature
        hc, hA = p.heat_capacity, p.heat_transfer
        tau = c.valve_tau
        lag = tau > 0
        vr0, vc0 = self.vr0, self.vc0
        pg0, vg0, ngas = p.gas_pressure, p.gas_volume, p.n_gas
        rho = p.oil_density
        pt2 = _P_TURB * _P_TURB
        hyst, fy, xy = c.preyield, c.preyield_force, c.preyield_displacement
        bwg, bwb, bwn = BW_GAMMA, BW_BETA, BW_N
        groove, agr, x0g, hgr, egr = (c.bypass_area > 0.0, c.bypass_area, c.bypass_center,
                                      0.5 * c.bypass_length, c.bypass_edge)
        kbp = p.piston_valve.discharge_coefficient * math.sqrt(2.0 / rho)
        seval = stroke.eval
        exp, log1p, tanh = math.exp, math.log1p, math.tanh

        flow, opening, beta_e = _fast_fluid(p)
        cp, cf_ = _valve_constants(p.piston_valve, rho), _valve_constants(self.foot, rho)
        vp, vf = p.piston_valve, self.foot

        def f(y, t):
            if hyst:
                da, vr, xb, vb, pR, pC, dv, temp, yp, yf, z = y
            else:
                da, vr, xb, vb, pR, pC, dv, temp, yp, yf = y
            s, sd = seval(t)
            x, xd = s - da - xb, vr - vb
            if gap > 0.0:
                z1, z2 = (da - hgap) / wgap, (-da - hgap) / wgap
                e1 = (z1 if z1 > 0 else 0.0) + log1p(exp(-abs(z1)))
                e2 = (z2 if z2 > 0 else 0.0) + log1p(exp(-abs(z2)))
                chi = 0.5 * (tanh(0.5 * z1) + tanh(0.5 * z2)) + 1.0
                ta = k * wgap * (e1 - e2) + cm * chi * (sd - vr)
            else:
                ta = k * da + cm * (sd - vr)
            thf = ff * tanh(xd / veps) if ff > 0.0 else 0.0
            if hyst:
                thf += fy * z
            th = pR * aa - pC * ap + P_ATM * ar + thf
            pres = pg0 * (vg0 / (vg0 - dv)) ** ngas
            phi = exp(-beta * (temp - tref)) if beta > 0.0 else 1.0
            dpp, dpf = pR - pC, pC - pres
            qp = flow(cp, dpp, phi, yp if lag else None)
            qf = flow(cf_, dpf, phi, yf if lag else None)
            if groove:
                g = 0.5 * (tanh((x - x0g + hgr) / egr) - tanh((x - x0g - hgr) / egr))
                qp += agr * g * kbp * dpp / (dpp * dpp + pt2) ** 0.25
            out = [sd - vr, (ta - th) / mr, vb, (th - k * xb - cm * vb) / mb,
                   beta_e(pR) / (vr0 - aa * x) * (aa * xd - qp),
                   beta_e(pC) / (vc0 + ap * x) * (-ap * xd + qp - qf), qf, 0.0, 0.0, 0.0]
            if beta > 0.0:
                out[IT] = (qp * dpp + qf * dpf + thf * xd - hA * (temp - tamb)) / hc
            if lag:
                yqp = opening(dpp / phi, vp.blowoff_crack, vp.blowoff_full, vp.smooth_blowoff)
                yqf = opening(dpf / phi, vf.blowoff_crack, vf.blowoff_full, vf.smooth_blowoff)
                out[IY_P] = (yqp - yp) / tau
                out[IY_F] = (yqf - yf) / tau
            if hyst:
                out.append(xd / xy * (1.0 - abs(z) ** bwn * (bwg * (1.0 if xd * z >= 0.0 else -1.0) + bwb)))
            return out

        return f

    def jac(self, y, t, stroke: StrokeInput) -> np.ndarray:
        """Analytic Jacobian d rhs / d y."""
        return self._eval(y, t, stroke, True)[1]

    def load_cell(self, states: np.ndarray, s: np.ndarray, sd: np.ndarray) -> np.ndarray:
        """Mount A tension [N] (load-cell reading before tare) for state rows."""
        d = states[:, ID_A]
        dd = sd - states[:, IV_R]
        k, cm, g = self.p.mount_stiffness, self.p.mount_damping, self.c.free_play
        if g <= 0:
            return k * d + cm * dd
        w, h = self.c.free_play_smoothing, 0.5 * g
        sp = lambda z: np.maximum(z, 0.0) + w * np.log1p(np.exp(-np.abs(z) / w))  # noqa: E731
        sg = lambda z: 0.5 * (1.0 + np.tanh(0.5 * z / w))  # noqa: E731
        return k * (sp(d - h) - sp(-d - h)) + cm * (sg(d - h) + sg(-d - h)) * dd

    # -------------------------------------------------------------- driver
    def simulate(self, t: np.ndarray, stroke: np.ndarray, t_out: np.ndarray | None = None,
                 rtol: float = 1e-7, hmax: float = 2e-3) -> DamperResponse:
        """Impose stroke [m] at times t [s] (cubic spline in between) starting from rest,
        and return the response on t_out [s] (default t). rtol: LSODA relative tolerance
        (absolute tolerances scale with it); hmax [s]: largest internal step."""
        t = np.asarray(t, dtype=float)
        stroke = np.asarray(stroke, dtype=float)
        t_out = t if t_out is None else np.asarray(t_out, dtype=float)
        if t.ndim != 1 or t.shape != stroke.shape or t.size < 2:
            raise ValueError("t and stroke must be 1-D arrays of equal length >= 2")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(stroke))):
            raise ValueError("t and stroke must be finite (no NaN/inf)")
        if np.any(np.diff(t) <= 0):
            raise ValueError("t must be strictly increasing")
        if np.any(np.diff(t_out) <= 0) or t_out[0] < t[0] or t_out[-1] > t[-1] + 1e-12:
            raise ValueError("t_out must be strictly increasing and inside [t[0], t[-1]]")
        if np.max(np.abs(stroke)) > self.p.travel - 0.005:
            raise ValueError(f"stroke exceeds the damper travel: |stroke| max "
                             f"{np.max(np.abs(stroke)):.4f} m > {self.p.travel - 0.005:.3f} m")
        inp = StrokeInput(t, stroke)
        y0 = self.static_state(float(stroke[0]))
        tare = float(self.load_cell(y0[None, :], np.array([stroke[0]]), np.array([0.0]))[0])
        # the damper starts at rest (the rig holds it still before the test)
        y0[IV_R] = y0[IV_B] = 0.0
        atol = rtol * ATOL_SCALE[:self.n_states]
        grid = t_out if t_out[0] == t[0] else np.concatenate(([t[0]], t_out))
        # LSODA (BDF when stiff) with the analytic Jacobian; with rtol = 1e-7 the force
        # error is a few N at most (step refinement in tests/test_campaign_rig.py)
        ys, info = odeint(self.fast_rhs(inp), y0, grid, Dfun=lambda y, tt: self.jac(y, tt, inp),
                          rtol=rtol, atol=atol, hmax=hmax, mxstep=500000, full_output=True)
        if info["message"] != "Integration successful.":
            raise RuntimeError(f"rig damper integration failed: {info['message']}")
        if grid is not t_out:
            ys = ys[1:]
        if ys.shape[1] < N_STATES:  # zeta = 0 when the Bouc-Wen element is off
            ys = np.hstack((ys, np.zeros((ys.shape[0], N_STATES - ys.shape[1]))))
        self.last_info = info
        s = inp(t_out)
        sd = inp(t_out, 1)
        sdd = inp(t_out, 2)
        force = self.load_cell(ys, s, sd) - tare
        vg = self.p.gas_volume
        p_res = self.p.gas_pressure * (vg / (vg - ys[:, IV_RES])) ** self.p.n_gas
        return DamperResponse(
            t=t_out, stroke=s, stroke_velocity=sd, stroke_acceleration=sdd, force=force,
            tare=tare, piston=s - ys[:, ID_A] - ys[:, IX_B], p_rebound=ys[:, IP_R],
            p_compression=ys[:, IP_C], p_reservoir=p_res, temperature=ys[:, IT].copy(),
            states=ys)
