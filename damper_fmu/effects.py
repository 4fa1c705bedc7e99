"""Optional effect elements of the lumped and two-chamber models (all off at their defaults).

They extend the base model with the physics a real damper (or rig) shows and the base model
lacks, for the diagnosis (design notes' catalogue). Sign convention: forces tension +, stroke
extension +, SI units; temperatures in degC.

* ``friction``: F += Ff tanh(v_eff / v_eps), in parallel (seals and guides; v_eff: the stroke
  velocity the damper sees, after the free play). In the two-chamber model the seal friction acts
  at the piston velocity inside the mounts (``models.TwoChamberModel``), not here (``inside``).
* ``preload``: F += F0 (un-tared reservoir gas force or load-cell offset; F0 < 0 for a gas force
  pushing the rod out).
* ``free_play``: dead band of total width g in series at the actuator end (backlash operator on
  the stroke): while the actuator crosses the gap the damper sees no motion and the load cell
  reads no damper force. In the two-chamber model the dead band is in its mount instead
  (``models.TwoChamberModel``, ``inside``): the mount carries no force inside the gap, so the
  chambers unload while the actuator crosses it, as on a real damper.
* ``thermal_drift``: the damping characteristic is scaled by exp(-beta (T - T_ref)); T is the
  measured oil temperature (input, ``thermal_source = 1``) or follows the thermal balance
  C dT/dt = F v - G (T - T_ref) (``thermal_source = 0``), solved exactly over each communication step with
  the power F v at its end (the explicit step it replaced diverged beyond steps of 2 C / G, 0.2 s at the
  extremes of C and G, and needed bounds on C and G that refused a small damper).
* ``valve_lag``: the valve opening lags the flow by tau; with the opening frozen, extra flow meets
  the valve-closed resistance c0 (the steepest slope of Fc,O) instead of the local slope Fc'(v):
  to first order
  F += tau (c0 - Fc'(v)) a, with the stroke velocity v and acceleration a the damper sees (the
  damping element's own rate moves much faster than the stroke beyond the knee, where its
  derivative would amplify every internal transient). Zero below the blow-off knee, a force lead
  beyond it (a late-opening valve overshoots).
* ``time_delay``: the force channel is delayed by d relative to the stroke: F_out(t) = F(t - d)
  (a DAQ skew, not damper physics: keep it out of a co-simulation model).
* ``inertia``: F += m_eq x1'' (fluid and rod inertia seen by the load cell).

Form elements beyond the catalogue (the diagnosis tries them when the catalogue leaves a residual):

* ``hysteresis`` (pre-yield hysteresis, a Dahl element in parallel, outside the mounts in both
  models): F += z with dz/dx = (s F_h - z) / x_h, s = sign(dx), x the stroke the damper sees. Per
  step the exact solution for a monotone stroke increment dx: z <- s F_h + (z - s F_h)
  exp(-|dx| / x_h). A rate-independent loop: stiffness F_h / x_h right after a reversal, F_h once
  the stroke has moved a few x_h (MR fluid below yield, seals sticking before they slide; friction,
  by contrast, switches within a velocity band).
* ``bypass`` (position-dependent damping: a groove past the piston near mid-stroke, or the
  opposite of an end-stop cushion): the damping characteristic is scaled by 1 - r b(x), with
  b(x) = (tanh((x - c + w/2) / e) - tanh((x - c - w/2) / e)) / 2 (1 inside the groove of length w
  around c, tanh ends of length e), x the stroke the damper sees at the start of each step; with a
  direction (+1: only in extension, v > 0, as a twin-tube groove in the pressure tube bypasses the
  piston valve in rebound while the foot valve sets compression; -1: only in compression) and a fade
  1 / (1 + (v / v_b)^2) beyond the speed v_b (past the blow-off knee the open valve carries most of
  the flow), v the stroke velocity seen at the start of each step (v_b = 0: no fade).
"""
from __future__ import annotations

import math
from collections import deque

__all__ = ["Effects"]


class Effects:
    """Effect elements of one simulation run; ``active`` is False when all are off."""

    def __init__(self, params: dict, inside: bool = False):
        """inside: the model carries the seal friction and the free play itself (two-chamber model):
        the friction force is not added here and the gap is 0 here."""
        p = params
        self.ff, self.v_eps = p.get("friction_force", 0.0), p.get("friction_velocity", 5e-4)
        self.inside = inside
        self.f0 = p.get("preload_force", 0.0)
        self.gap = 0.0 if inside else p.get("free_play", 0.0)
        self.beta = p.get("thermal_beta", 0.0)
        self.heat_c, self.heat_g = p.get("thermal_capacity", 4000.0), p.get("thermal_conductance", 5.0)
        self.t_ref = p.get("thermal_reference", 20.0)
        self.tau = p.get("valve_tau", 0.0)
        self.delay = p.get("time_delay", 0.0)
        self.m_eq = p.get("inertia_mass", 0.0)
        self.fh, self.xh = p.get("hysteresis_force", 0.0), p.get("hysteresis_displacement", 5e-4)
        self.bp_r, self.bp_c = p.get("bypass_ratio", 0.0), p.get("bypass_center", 0.0)
        self.bp_w, self.bp_e = p.get("bypass_width", 0.01), p.get("bypass_edge", 1e-3)
        self.bp_d, self.bp_v = p.get("bypass_direction", 0.0), p.get("bypass_velocity", 0.0)
        self.active = any(v != 0.0 for v in (self.ff, self.f0, self.gap, self.beta, self.tau, self.delay,
                                              self.m_eq, self.fh, self.bp_r))
        # state
        self.x_seen = 0.0  # stroke [m] the damper saw at the end of the last step
        self.v_seen = 0.0  # and its velocity [m/s]
        self.z = 0.0  # hysteresis force [N]
        self.x_eff = 0.0
        self.engaged = True
        self.temperature = self.t_ref
        self.time = 0.0
        self.history: deque = deque()

    # -- state ------------------------------------------------------------------------------
    def initialize(self, x1: float, force: float, v1: float = 0.0) -> None:
        self.x_eff, self.engaged, self.temperature, self.time = x1, True, self.t_ref, 0.0
        self.x_seen, self.v_seen, self.z = x1, v1, 0.0
        self.history = deque([(0.0, force)])

    def get_state(self) -> list:
        flat = [v for pair in self.history for v in pair]
        return [self.x_eff, float(self.engaged), self.temperature, self.time, self.x_seen, self.v_seen, self.z, *flat]

    def set_state(self, s) -> None:
        self.x_eff, engaged, self.temperature, self.time, self.x_seen, self.v_seen, self.z = (float(v) for v in s[:7])
        self.engaged = engaged != 0.0
        rest = [float(v) for v in s[7:]]
        self.history = deque(zip(rest[0::2], rest[1::2]))

    # -- pieces used by the simulator ---------------------------------------------------------
    def damping_scale(self) -> float:
        """Factor [1] on the damping characteristic for the next step: thermal drift and bypass."""
        scale = math.exp(-self.beta * (self.temperature - self.t_ref)) if self.beta else 1.0
        v = self.v_seen
        if self.bp_r and not ((self.bp_d > 0.5 and v <= 0.0) or (self.bp_d < -0.5 and v >= 0.0)):
            u = self.x_seen - self.bp_c
            half = 0.5 * self.bp_w
            q = v / self.bp_v if self.bp_v else 0.0
            r = self.bp_r / (1.0 + q * q)
            scale *= 1.0 - r * 0.5 * (math.tanh((u + half) / self.bp_e) - math.tanh((u - half) / self.bp_e))
        return scale

    def play(self, state: tuple[float, bool], x1: float, v1: float) -> tuple[tuple[float, bool], float, float]:
        """Backlash operator of the free play: from the gap state (x_eff [m], engaged) and the
        actuator stroke x1 [m] / velocity v1 [m/s], the new state and the stroke and velocity the
        damper sees. Pure (no state change here): the integrator commits the state of an
        accepted step only."""
        x_eff, engaged = state
        if not self.gap:
            return state, x1, v1
        half = 0.5 * self.gap
        if x1 - x_eff >= half:  # pulling on the tension side of the gap
            x_eff, engaged = x1 - half, True
        elif x1 - x_eff <= -half:  # pushing on the compression side
            x_eff, engaged = x1 + half, True
        else:  # crossing the gap
            engaged = False
        return (x_eff, engaged), x_eff, (v1 if engaged else 0.0)

    def output(self, f_model: float, h: float, x_eff: float, v_eff: float, a1: float, valve_gain: float,
               temperature_input: float | None) -> float:
        """Measured force [N] at the end of a step of h [s] from the model force f_model [N].

        x_eff [m], v_eff [m/s]: stroke and velocity the damper sees at the end of the step; a1
        [m/s^2]: stroke acceleration; valve_gain [N s/m]: c0 - Fc'(v_eff); temperature_input [degC]
        or None.
        """
        f = f_model if (self.engaged or not self.gap) else 0.0
        if self.fh:
            dx = x_eff - self.x_seen
            if dx != 0.0:
                sat = self.fh if dx > 0.0 else -self.fh
                self.z = sat + (self.z - sat) * math.exp(-abs(dx) / self.xh)
            if self.engaged or not self.gap:
                f += self.z
        self.x_seen, self.v_seen = x_eff, v_eff
        if self.ff and not self.inside:
            f += self.ff * math.tanh(v_eff / self.v_eps)
        if self.tau and (self.engaged or not self.gap):
            f += self.tau * valve_gain * a1
        if self.m_eq:
            f += self.m_eq * a1
        f += self.f0
        if self.beta:
            if temperature_input is not None:
                self.temperature = temperature_input
            else:  # the thermal balance solved exactly over the step at its power: stable at any step and scale
                power = f_model * v_eff
                decay = -math.expm1(-h * self.heat_g / self.heat_c)  # 1 - exp(-h G / C)
                self.temperature += (power / self.heat_g - (self.temperature - self.t_ref)) * decay
        self.time += h
        if not self.delay:
            return f
        hist = self.history
        hist.append((self.time, f))
        target = self.time - self.delay
        while len(hist) > 2 and hist[1][0] <= target:
            hist.popleft()
        (t0, f0), (t1, f1) = hist[0], hist[1] if len(hist) > 1 else hist[0]
        if target <= t0 or t1 == t0:
            return f0
        return f0 + (f1 - f0) * (target - t0) / (t1 - t0)
