"""Damper model equations: the single source used by the FMUs and every in-process engine.

Sign convention: positions positive in extension (away from the frame), element elongation
and elongation rate positive in extension, element forces positive in tension. The output
force is the force the damper transmits at the actuator end, positive in tension.

Lumped model (paper section 2.1, with physically consistent signs; the printed eqs. 1-3 are not):

    actuator x1 --[block A: kB, cB]-- MP (x2) --[Fc,O(u)]-- MO (x3) --[Fk,O(e)]-- MC (x4) --[block B: kB, cB]-- frame

    MP x2'' = FA - Fc(u)          FA = kB (x1 - x2) + cB (x1' - x2'),   u = x2' - x3'
    MO x3'' = Fc(u) - Fk(e)       e  = x3 - x4
    MC x4'' = Fk(e) - FB          FB = kB x4 + cB x4'
    output F = FA                 (paper eq. 4)

Maxwell model: spring k_s in series with a linear dashpot c; state xd = dashpot end position,
F = k_s (x1 - xd) = c xd'. Table Maxwell model: same with the dashpot force Fc,O(xd').

Two-chamber model (a twin-tube form: rebound and compression chambers, piston and foot valves;
massless, the oil's compressibility is the series stiffness):

    actuator x1 --[mounts kM, cM]-- piston y --| rebound chamber R | compression chamber C | reservoir |

    fR' = kR(y, fR) (y' - up)           fR = Aa pR, gauge force of R (Aa: annulus area)
    gC' = kC(y, gC) (-y' + a up - uf)   gC = Ap pC, gauge force of C (Ap: piston area), a = Aa / Ap
    fR - a gC = Fp(up)    piston valve, up = its flow / Aa: up > 0 the rebound half of Fc,O, up < 0
                          the check valve (slope check_damping; 0: CHECK_SHARE of Fc,O's mean slope)
    gC = Ff(uf)           foot valve, uf = its flow / Ap: uf > 0 Ff(u) = -Fc,O(-u / (1 - a)) / (1 - a),
                          so that the steady compression force is Fc,O(v); uf < 0 the intake check
    fR - gC + Ff tanh(y' / v_eps) = kM (x1 - y) + cM (x1' - y')   (Ff: seal friction, effect 'friction')
    output F = fR - gC + Ff tanh(y' / v_eps) + k_gas (x1 - x_ref)   (reservoir gas spring, zero at the
                                                                    start stroke x_ref)
    kR(y, fR) = k_R / (1 - y / L_R) / (1 + air (1 + fR / (a f_res))^-1.714)
    kC(y, gC) = k_C / (1 + y / L_C) / (1 + air (1 + gC / f_res)^-1.714)

(chamber volumes shrink and grow with the piston position y, the volume ratio clipped at 0.05;
entrained air compressed isentropically, exponent 1 + 1/1.4, with the pressure ratio
1 + f / (A p_res) floored smoothly at 0.05, so that a chamber sucked towards cavitation by a
very fast stroke stays soft but finite and Newton's method sees a smooth stiffness). After every reversal
both chambers are sealed (stiffness ~ kR + a^2 kC) until a check valve opens: the behaviour the
lumped model's single series spring cannot produce (docs/twin-tube-form-study.md). At constant velocity v the
force is Fc,O(v) + check_damping (1 - a)^2 v in rebound, Fc,O(v) + check_damping v in compression.

Each model exposes ``stage(yb, g, x1, v1)``: the solution y of the implicit stage equation
``y = yb + g f(y; x1, v1)`` (one stage of an SDIRK scheme), solved exactly by Newton's method on
the piecewise-linear characteristics (within the right pieces the equations are linear, so the
iteration ends when the pieces stop changing).
"""
from __future__ import annotations

import math
import sys
from bisect import bisect_right as bisect_segment  # the lookup of PwlTable.segment, inlined

from .parameters import check_values
from .tables import PwlTable

__all__ = ["ConvergenceError", "DIAGNOSTICS", "LumpedModel", "MaxwellModel", "MaxwellTableModel", "TwoChamberModel",
           "make_model"]

_MAX_NEWTON = 12  # plain piecewise-linear Newton; then the damped fallback
#: What double precision resolves of a sum of terms, relative to the sum of their magnitudes (4 units of
#: rounding): where every iterative solve of the models ends (the two-chamber stage's tolerance floor
#: ``TwoChamberModel._tolerance``, the lumped model's damped Newton, the width of a closed bisection bracket).
#: A residual of terms far larger than the force scale (a stiff mount times a stroke of mm on a damper of
#: newtons) cannot get below it; relative, it holds at every force and stroke scale.
_RESOLUTION = 4.0 * sys.float_info.epsilon

#: Internal element outputs of each model (``diagnostics``, FMU outputs): name -> (unit, text),
#: in the order of ``diagnostics``.
DIAGNOSTICS: dict[str, dict[str, tuple[str, str]]] = {
    "lumped": {
        "blockA_elongation": ("m", "Silent block A elongation x1 - x2"),
        "blockA_rate": ("m/s", "Silent block A elongation rate"),
        "damping_rate": ("m/s", "Damping element Fc,O elongation rate x2' - x3'"),
        "damping_force": ("N", "Damping element force Fc,O"),
        "elastic_elongation": ("m", "Elastic element Fk,O elongation x3 - x4"),
        "elastic_force": ("N", "Elastic element force Fk,O"),
        "blockB_elongation": ("m", "Silent block B elongation x4"),
        "blockB_force": ("N", "Silent block B force (frame reaction)"),
    },
    "maxwell": {"spring_elongation": ("m", "Series spring elongation")},
    "maxwell_table": {"spring_elongation": ("m", "Series spring elongation")},
    "twochamber": {
        "mount_elongation": ("m", "Mount elongation x1 - y"),
        "rebound_chamber_force": ("N", "Rebound-chamber gauge pressure times annulus area"),
        "compression_chamber_force": ("N", "Compression-chamber gauge pressure times piston area"),
        "piston_valve_rate": ("m/s", "Piston-valve flow / annulus area (+ rebound damping, - check)"),
        "foot_valve_rate": ("m/s", "Foot-valve flow / piston area (+ compression damping, - intake check)"),
    },
}


class ConvergenceError(RuntimeError):
    """The implicit stage equation could not be solved (e.g. a non-monotonic table)."""


def _table(params: dict, prefix: str, axis: str) -> PwlTable:
    n = sum(1 for k in params if k.startswith(f"{prefix}_{axis}"))
    xs = [params[f"{prefix}_{axis}{i:02d}"] for i in range(1, n + 1)]
    fs = [params[f"{prefix}_{i:02d}"] for i in range(1, n + 1)]
    return PwlTable(xs, fs)


class LumpedModel:
    """Nonlinear lumped damper model; state y = [x2, x3, x4, v2, v3, v4] in m and m/s."""

    kind = "lumped"
    n_state = 6

    def __init__(self, params: dict[str, float] | None = None):
        p = check_values("lumped", params or {})
        self.params = p
        self.mC, self.mO, self.mP = p["M_C"], p["M_O"], p["M_P"]
        self.kB, self.cB = p["k_B"], p["c_B"]
        self.fk = _table(p, "Fk", "x")
        self.fc = _table(p, "Fc", "v")
        self._consts: tuple | None = None
        #: factor on the damping characteristic Fc,O (thermal drift effect; 1 = base model)
        self.damping_scale = 1.0

    def initial_state(self, x1: float, v1: float) -> list[float]:
        """Force-free state at stroke x1 [m]: all elements unloaded, the dashpot carries the offset.

        MP and MO move with the actuator velocity v1 [m/s], so the output force starts at zero.
        """
        return [x1, 0.0, 0.0, v1, v1, 0.0]

    def force(self, y, x1: float, v1: float) -> float:
        """Output force FA [N], positive in tension."""
        return self.kB * (x1 - y[0]) + self.cB * (v1 - y[3])

    def force_scale(self) -> float:
        """Force scale [N] of the integrator's error tolerance: the largest |Fc,O| ordinate."""
        return self.fc.peak

    def error_norm(self, ya, yb) -> float:
        """Difference [N] between two states, as the silent-block forces they imply
        (the output force and the frame force at equal inputs)."""
        return max(abs(self.kB * (yb[0] - ya[0]) + self.cB * (yb[3] - ya[3])),
                   abs(self.kB * (yb[2] - ya[2]) + self.cB * (yb[5] - ya[5])))

    def _stage_constants(self, g: float) -> tuple:
        """Constants of the stage equations for the stage coefficient g [s] and the current
        damping scale (cached: both rarely change)."""
        mP, mO, mC = self.mP / g, self.mO / g, self.mC / g
        kBg = self.kB * g
        ds = self.damping_scale
        fi, fs = self.fc.intercept, self.fc.slope
        if ds != 1.0:
            fi, fs = [ds * a for a in fi], [ds * b for b in fs]
        c = (g, mP, mO, mC, mP + kBg + self.cB, mC + kBg + self.cB, self.kB, self.cB,
             self.fc.breaks, fi, fs, self.fk.breaks, self.fk.intercept, self.fk.slope, ds)
        self._consts = c
        return c

    def stage(self, yb, g: float, x1: float, v1: float) -> list[float]:
        """Solve y = yb + g f(y) for the lumped model (x1 [m], v1 [m/s] at the stage time).

        Positions are eliminated (x = xb + g v); the velocities solve a symmetric tridiagonal
        system, linear within the current pieces of Fc,O and Fk,O. The first pieces tried are
        those of the base point yb.
        """
        x2b, x3b, x4b, v2b, v3b, v4b = yb
        c = self._consts
        if c is None or c[0] != g or c[14] != self.damping_scale:
            c = self._stage_constants(g)
        _, mP, mO, mC, d2, d4, kB, cB, bc, ia, sa, bk, ka, ks, _ = c
        dxb = x3b - x4b
        # Constant parts of the right-hand sides.
        r2 = mP * v2b + kB * (x1 - x2b) + cB * v1
        r3 = mO * v3b
        r4 = mC * v4b - kB * x4b
        ic = bisect_segment(bc, v2b - v3b)
        ik = bisect_segment(bk, dxb + g * (v3b - v4b))
        for _ in range(_MAX_NEWTON):
            sc, ac = sa[ic], ia[ic]
            skg = ks[ik] * g
            akx = ka[ik] + ks[ik] * dxb
            # Tridiagonal system [d2+sc, -sc, 0; -sc, mO+sc+skg, -skg; 0, -skg, d4+skg] v = b.
            a11 = d2 + sc
            w1 = -sc / a11
            y1 = (r2 - ac) / a11
            a22 = mO + sc + skg + sc * w1
            w2 = -skg / a22
            y2 = (r3 + ac - akx + sc * y1) / a22
            a33 = d4 + skg + skg * w2
            if a11 <= 0.0 or a22 <= 0.0 or a33 <= 0.0:
                raise ConvergenceError("stage Jacobian not positive definite (non-monotonic table?)")
            v4 = (r4 + akx + skg * y2) / a33
            v3 = y2 - w2 * v4
            v2 = y1 - w1 * v3
            jc = bisect_segment(bc, v2 - v3)
            jk = bisect_segment(bk, dxb + g * (v3 - v4))
            if jc == ic and jk == ik:
                return [x2b + g * v2, x3b + g * v3, x4b + g * v4, v2, v3, v4]
            ic, ik = jc, jk
        return self._stage_damped(yb, g, x1, v1)

    def _stage_damped(self, yb, g: float, x1: float, v1: float) -> list[float]:
        """Fallback when plain Newton cycles between table pieces: damped Newton.

        The stage residual is the gradient of the convex, C1, piecewise-quadratic potential
        ``_potential`` (for monotone tables), so Newton steps with backtracking on it converge. It ends
        where double precision does: the Newton step within ``_RESOLUTION`` of the velocities, or the
        residuals [N] within ``_RESOLUTION`` of the magnitudes of their terms (an absolute step of 1e-15
        m/s was the end before: no precision at all on a stroke of nanometres).
        """
        x2b, x3b, x4b, v2b, v3b, v4b = yb
        c = self._consts
        if c is None or c[0] != g or c[14] != self.damping_scale:
            c = self._stage_constants(g)
        _, mP, mO, mC, d2, d4, kB, cB, bc, ia, sa, bk, ka, ks, _ = c
        dxb = x3b - x4b
        v = [v2b, v3b, v4b]
        phi = self._potential(v, yb, g, x1, v1)
        for _ in range(200):
            v2, v3, v4 = v
            u, e = v2 - v3, dxb + g * (v3 - v4)
            ic, ik = bisect_segment(bc, u), bisect_segment(bk, e)
            sc, skg = sa[ic], ks[ik] * g
            fcu, fke = ia[ic] + sc * u, ka[ik] + ks[ik] * e
            # residuals and Newton direction (same tridiagonal Jacobian as in ``stage``)
            r = [mP * (v2 - v2b) - kB * (x1 - x2b - g * v2) - cB * (v1 - v2) + fcu,
                 mO * (v3 - v3b) - fcu + fke,
                 mC * (v4 - v4b) - fke + kB * (x4b + g * v4) + cB * v4]
            a11, a22, a33 = d2 + sc, mO + sc + skg, d4 + skg
            w1 = -sc / a11
            a22 -= sc * sc / a11
            w2 = -skg / a22
            a33 -= skg * skg / a22
            y1 = -r[0] / a11
            y2 = (-r[1] + sc * y1) / a22
            d3 = (-r[2] + skg * y2) / a33
            d2_ = y2 - w2 * d3
            d1 = y1 - w1 * d2_
            scale = abs(d1) + abs(d2_) + abs(d3)
            size = (mP * (abs(v2) + abs(v2b)) + mO * (abs(v3) + abs(v3b)) + mC * (abs(v4) + abs(v4b))
                    + kB * (abs(x1) + abs(x2b) + abs(x4b) + g * (abs(v2) + abs(v4)))
                    + cB * (abs(v1) + abs(v2) + abs(v4))
                    + 2.0 * (abs(fcu) + abs(fke)) + sc * (abs(v2) + abs(v3)) + skg * (abs(v3) + abs(v4))
                    + ks[ik] * abs(dxb))
            if (scale <= _RESOLUTION * (abs(v2) + abs(v3) + abs(v4))
                    or abs(r[0]) + abs(r[1]) + abs(r[2]) <= _RESOLUTION * size):
                return [x2b + g * v2, x3b + g * v3, x4b + g * v4, v2, v3, v4]
            alpha = 1.0
            while True:
                trial = [v2 + alpha * d1, v3 + alpha * d2_, v4 + alpha * d3]
                phi_t = self._potential(trial, yb, g, x1, v1)
                if phi_t <= phi or alpha < 1e-12:
                    break
                alpha *= 0.5
            v, phi = trial, phi_t
        raise ConvergenceError("lumped model stage: damped Newton did not converge (non-monotonic table?)")

    def _potential(self, v, yb, g: float, x1: float, v1: float) -> float:
        """Convex potential whose gradient is the stage residual (see ``stage``), in W."""
        x2b, x3b, x4b, v2b, v3b, v4b = yb
        v2, v3, v4 = v
        kB, cB = self.kB, self.cB
        e = x3b - x4b + g * (v3 - v4)
        return (0.5 * (self.mP * (v2 - v2b) ** 2 + self.mO * (v3 - v3b) ** 2 + self.mC * (v4 - v4b) ** 2) / g
                + 0.5 * kB / g * ((x1 - x2b - g * v2) ** 2 + (x4b + g * v4) ** 2)
                + 0.5 * cB * ((v1 - v2) ** 2 + v4 * v4)
                + self.damping_scale * self.fc.primitive(v2 - v3) + self.fk.primitive(e) / g)

    def valve_gain(self, u: float) -> float:
        """c0 - Fc'(u) [N s/m] (valve lag effect): see :func:`valve_gain`."""
        return valve_gain(self.fc, self.damping_scale, u)

    def diagnostics(self, y, x1: float, v1: float) -> dict[str, float]:
        """Internal elongations [m], rates [m/s] and element forces [N] (positive in tension)."""
        x2, x3, x4, v2, v3, v4 = y
        u, e = v2 - v3, x3 - x4
        return {
            "blockA_elongation": x1 - x2,
            "blockA_rate": v1 - v2,
            "damping_rate": u,
            "damping_force": self.damping_scale * self.fc(u),
            "elastic_elongation": e,
            "elastic_force": self.fk(e),
            "blockB_elongation": x4,
            "blockB_force": self.kB * x4 + self.cB * v4,
        }


def valve_gain(fc: PwlTable, damping_scale: float, u: float) -> float:
    """c0 - Fc'(u) [N s/m]: the valve-closed resistance c0 (steepest slope of the damping table ``fc``
    on the side of u) minus the local slope at the rate u [m/s], times the damping scale (valve lag
    effect: zero where the characteristic is at its steepest, largest beyond the blow-off knee)."""
    k0 = fc.segment(0.0)  # first piece with positive abscissae
    side = fc.slope[k0:] if u >= 0.0 else fc.slope[:k0]
    return damping_scale * (max(side) - fc.slope[fc.segment(u)])


class _SeriesSpringModel:
    """Shared part of the Maxwell models: a spring k_s [N/m] in series with a dashpot;
    state y = [xd], the dashpot end position [m]; F = k_s (x1 - xd)."""

    n_state = 1
    ks: float

    def initial_state(self, x1: float, v1: float) -> list[float]:
        """Force-free state at stroke x1 [m] (spring unloaded)."""
        return [x1]

    def force(self, y, x1: float, v1: float) -> float:
        return self.ks * (x1 - y[0])

    def error_norm(self, ya, yb) -> float:
        """Difference [N] between two states, as the spring forces they imply."""
        return abs(self.ks * (yb[0] - ya[0]))

    def diagnostics(self, y, x1: float, v1: float) -> dict[str, float]:
        return {"spring_elongation": x1 - y[0]}


class MaxwellModel(_SeriesSpringModel):
    """Linear Maxwell model: spring k_s in series with a linear dashpot c."""

    kind = "maxwell"

    def __init__(self, params: dict[str, float] | None = None):
        p = check_values("maxwell", params or {})
        self.params = p
        self.ks, self.c = p["k_s"], p["c"]

    def force_scale(self) -> float:
        """Force scale [N] of the integrator's error tolerance: the dashpot force at 0.1 m/s."""
        return self.c * 0.1

    def stage(self, yb, g: float, x1: float, v1: float) -> list[float]:
        """Solve xd = xdb + g k_s (x1 - xd) / c (linear, exact)."""
        a = g * self.ks / self.c
        return [(yb[0] + a * x1) / (1.0 + a)]


class MaxwellTableModel(_SeriesSpringModel):
    """Maxwell model with a piecewise-linear dashpot Fc,O."""

    kind = "maxwell_table"

    def __init__(self, params: dict[str, float] | None = None):
        p = check_values("maxwell_table", params or {})
        self.params = p
        self.ks = p["k_s"]
        self.fc = _table(p, "Fc", "v")

    def force_scale(self) -> float:
        """Force scale [N] of the integrator's error tolerance: the largest |Fc,O| ordinate."""
        return self.fc.peak

    def stage(self, yb, g: float, x1: float, v1: float) -> list[float]:
        """Solve Fc(vd) = k_s (x1 - xdb - g vd) for the dashpot rate vd, then xd = xdb + g vd."""
        fc, ks = self.fc, self.ks
        rhs = ks * (x1 - yb[0])
        kg = ks * g
        i = fc.segment(rhs / (fc.slope[len(fc.slope) // 2] + kg))
        for _ in range(_MAX_NEWTON):
            den = fc.slope[i] + kg
            if den <= 0.0:
                raise ConvergenceError("Maxwell table stage: non-monotonic dashpot table")
            vd = (rhs - fc.intercept[i]) / den
            j = bisect_segment(fc.breaks, vd)
            if j == i:
                return [yb[0] + g * vd]
            i = j
        # cycling between pieces: bisection on the monotone residual Fc(vd) + k_s g vd - rhs
        h = lambda z: fc(z) + kg * z - rhs  # noqa: E731
        lo, hi = -1.0, 1.0
        while h(lo) > 0.0:
            lo *= 2.0
        while h(hi) < 0.0:
            hi *= 2.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if h(mid) > 0.0:
                hi = mid
            else:
                lo = mid
            if hi - lo <= _RESOLUTION * max(abs(lo), abs(hi)):
                break
        return [yb[0] + g * 0.5 * (lo + hi)]


#: Two-chamber model: isentropic air exponent 1 + 1/1.4, clip of the volume and pressure ratios,
#: Newton tolerance (sum of |residuals| relative to the force scale, never below ``_RESOLUTION`` of their
#: terms: ``TwoChamberModel._tolerance``) and iteration limits.
AIR_EXPONENT = 1.714
_TC_CLIP = 0.05
_TC_TOL = 1e-10
_TC_MAX_NEWTON = 60
_TC_PLAIN = 12
_TC_MAX_HALVINGS = 40
_TC_MAX_NESTED = 200
#: a mount whose stiffness and damping, linearised inside its dead band, are below this share of the engaged
#: mount's carries no force there: the stage's first guess keeps the last piston velocity
_TC_DISENGAGED = 1e-6
#: smoothing width [m] of the two-chamber mount's dead band (free play); the gap's edges are kinks
#: smoothed over this width (the limit gap -> 0 is the mount without play)
PLAY_SMOOTHING = 1e-5
#: the check valves' slope when ``check_damping`` is 0 (its default): this share of the damping table's mean slope
#: to its last rate, force_scale / the largest |rate abscissa| (the preset's: 25.3 kN at 0.1 m/s, 1.01e3 N s/m;
#: a fixed 1e3 N s/m was 50 N at 0.05 m/s on a 25 N damper, 4 times its table there: issue 74). It follows the
#: damper's table, so a damper scaled consistently keeps its check valves in proportion
CHECK_SHARE = 4e-3


def _sigmoid(z: float) -> float:
    """1 / (1 + exp(-z)), without overflow; as the C kernel's ``sigmoid``."""
    if z >= 0.0:
        return 1.0 / (1.0 + math.exp(-z))
    ez = math.exp(z)
    return ez / (1.0 + ez)


def _abs_sum(r: list[float], n: int) -> float:
    """|r[0]| + ... + |r[n-1]|, added left to right as the C kernel does (not sum(): Python 3.12's
    compensated float sum would differ from C in the last bits)."""
    s = abs(r[0])
    for i in range(1, n):
        s += abs(r[i])
    return s


def _solve_stage(jac: list[list[float]], r: list[float]) -> list[float] | None:
    """Solve the full two-chamber stage system jac d = r (unknowns w, up, uf, fR, gC) by its pattern: rows 3
    and 4 give gC from uf and fR from w and uf (unit pivots), the other rows then form a 3 x 3 system in
    (w, up, uf) for ``_solve``; None when singular. Written as the C kernel's ``tc_solve_stage``."""
    if abs(jac[3][4]) < 1e-300 or abs(jac[4][3]) < 1e-300:
        return None
    a3, b3 = r[3] / jac[3][4], -jac[3][2] / jac[3][4]  # d_gC = a3 + b3 d_uf
    a4 = (r[4] - jac[4][4] * a3) / jac[4][3]  # d_fR = a4 + c4 d_w + b4 d_uf
    c4, b4 = -jac[4][0] / jac[4][3], -jac[4][4] * b3 / jac[4][3]
    a = [[jac[0][0] + jac[0][3] * c4, jac[0][1], jac[0][3] * b4],
         [jac[1][0], jac[1][1], jac[1][2] + jac[1][4] * b3],
         [jac[2][3] * c4, jac[2][1], jac[2][3] * b4 + jac[2][4] * b3]]
    b = [r[0] - jac[0][3] * a4, r[1] - jac[1][4] * a3, r[2] - jac[2][3] * a4 - jac[2][4] * a3]
    x = _solve(a, b)
    if x is None:
        return None
    return [x[0], x[1], x[2], a4 + c4 * x[0] + b4 * x[2], a3 + b3 * x[2]]


def _solve(a: list[list[float]], b: list[float]) -> list[float] | None:
    """Solve the n x n system a x = b (n <= 5) by Gaussian elimination with partial pivoting (a, b
    copied); None when singular. Written as the C kernel's ``solve_n``, operation for operation."""
    m = [row[:] + [bi] for row, bi in zip(a, b)]
    n = len(b)
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(m[i][k]) > abs(m[p][k]):
                p = i
        if abs(m[p][k]) < 1e-300:
            return None
        if p != k:
            m[k], m[p] = m[p], m[k]
        for i in range(k + 1, n):
            f = m[i][k] / m[k][k]
            for j in range(k, n + 1):
                m[i][j] -= f * m[k][j]
    x = [0.0] * n
    for i in range(n - 1, -1, -1):
        s_ = m[i][n]
        for j in range(i + 1, n):
            s_ -= m[i][j] * x[j]
        x[i] = s_ / m[i][i]
    return x


class TwoChamberModel:
    """Two-chamber (twin-tube) damper model; state y = [y, fR, gC, x_ref, up, uf, w] in m, N, N, m,
    m/s, m/s, m/s (piston position, chamber forces, start stroke of the gas spring, the valve rates
    and the piston velocity of the last stage: the friction force needs w, the rates start Newton)."""

    kind = "twochamber"
    n_state = 7

    def __init__(self, params: dict[str, float] | None = None):
        p = check_values("twochamber", params or {})
        self.params = p
        self.kM, self.cM = p["k_M"], p["c_M"]
        self.kR, self.kC, self.a = p["k_R"], p["k_C"], p["area_ratio"]
        self.LR, self.LC, self.air, self.fres, self.kgas = p["L_R"], p["L_C"], p["air"], p["f_res"], p["k_gas"]
        self.fc = _table(p, "Fc", "v")
        self.ffr, self.v_eps = p["friction_force"], p["friction_velocity"]
        #: free play [m]: a dead band in the mount spring (effect; 0 = base model), see ``mount``
        self.gap = p["free_play"]
        #: factor on the valve characteristics (thermal drift effect; 1 = base model)
        self.damping_scale = 1.0
        #: the check valves' slope [N s/m]: ``check_damping``, or 0 for CHECK_SHARE of the table's mean slope
        self.check_damping = p["check_damping"] or CHECK_SHARE * self.fc.peak / max(abs(x) for x in self.fc.xs)
        cchk, r = self.check_damping, 1.0 - self.a
        pos = [(x, f) for x, f in zip(self.fc.xs, self.fc.fs) if x > 0.0]
        neg = [(x, f) for x, f in zip(self.fc.xs, self.fc.fs) if x < 0.0][::-1]
        self.fp = PwlTable([-1.0] + [x for x, _ in pos], [-cchk] + [f for _, f in pos])
        self.ff = PwlTable([-1.0] + [-r * x for x, _ in neg], [-cchk] + [-f / r for _, f in neg])
        self._tol = _TC_TOL * self.force_scale()

    def initial_state(self, x1: float, v1: float) -> list[float]:
        """Force-free state at stroke x1 [m]: chambers at reservoir pressure, mounts unloaded, the
        piston moving with the actuator (v1 [m/s]; with friction the force starts at Ff tanh(v1 / v_eps))."""
        return [x1, 0.0, 0.0, x1, 0.0, 0.0, v1]

    def force(self, y, x1: float, v1: float) -> float:
        """Output force [N], positive in tension."""
        f = y[1] - y[2] + self.kgas * (x1 - y[3])
        if self.ffr:
            f += self.ffr * math.tanh(y[6] / self.v_eps)
        return f

    def valve_gain(self, u: float) -> float:
        """c0 - Fc'(u) [N s/m] (valve lag effect): see :func:`valve_gain`."""
        return valve_gain(self.fc, self.damping_scale, u)

    def force_scale(self) -> float:
        """Force scale [N] of the integrator's error tolerance: the largest |Fc,O| ordinate."""
        return self.fc.peak

    def mount(self, e: float, edot: float) -> tuple[float, float, float]:
        """Mount force [N] at elongation e [m] and rate edot [m/s] (tension +) with its partials
        (dF/de [N/m], dF/dedot [N s/m]). Without free play k_M e + c_M edot. With a free play g
        the spring has a dead band of width g and the damper acts only where the spring is
        engaged, smoothed over PLAY_SMOOTHING (as the rig's mount): inside the gap the mount
        carries no force and the chambers unload."""
        if not self.gap:
            return self.kM * e + self.cM * edot, self.kM, self.cM
        h, w = 0.5 * self.gap, PLAY_SMOOTHING
        z1, z2 = (e - h) / w, (-e - h) / w
        # dead band: softplus((e - h) / w) - softplus((-e - h) / w), times w
        d = w * (max(z1, 0.0) + math.log1p(math.exp(-abs(z1))) - max(z2, 0.0) - math.log1p(math.exp(-abs(z2))))
        s1, s2 = _sigmoid(z1), _sigmoid(z2)
        chi = s1 + s2
        dchi = (s1 * (1.0 - s1) - s2 * (1.0 - s2)) / w
        return self.kM * d + self.cM * chi * edot, self.kM * chi + self.cM * dchi * edot, self.cM * chi

    def error_norm(self, ya, yb) -> float:
        """Difference [N] between two states, as the chamber forces they imply."""
        return max(abs(yb[1] - ya[1]), abs(yb[2] - ya[2]))

    def stiffness(self, y: float, fR: float, gC: float) -> tuple[float, ...]:
        """Chamber stiffnesses [N/m] at piston position y [m] and chamber forces fR, gC [N], with
        their derivatives: (kR, dkR/dy, dkR/dfR, kC, dkC/dy, dkC/dgC)."""
        s = 1.0 - y / self.LR
        if s > _TC_CLIP:
            kR = self.kR / s
            kRy = kR / (self.LR * s)
        else:
            kR, kRy = self.kR / _TC_CLIP, 0.0
        s = 1.0 + y / self.LC
        if s > _TC_CLIP:
            kC = self.kC / s
            kCy = -kC / (self.LC * s)
        else:
            kC, kCy = self.kC / _TC_CLIP, 0.0
        kRf = kCg = 0.0
        if self.air > 0.0:
            for side in (0, 1):
                scale = self.a * self.fres if side == 0 else self.fres
                e = (fR if side == 0 else gC) / scale + 1.0 - _TC_CLIP  # absolute / reservoir pressure - floor
                root = math.sqrt(e * e + _TC_CLIP * _TC_CLIP)
                ratio = _TC_CLIP + 0.5 * (e + root)  # smooth floor: never below 0.05, C-infinity
                q = ratio ** -AIR_EXPONENT
                dq = -AIR_EXPONENT * q / ratio * (0.5 * (1.0 + e / root)) / scale
                d = 1.0 + self.air * q
                if side == 0:
                    kR, kRy = kR / d, kRy / d
                    kRf = -kR * self.air * dq / d
                else:
                    kC, kCy = kC / d, kCy / d
                    kCg = -kC * self.air * dq / d
        return kR, kRy, kRf, kC, kCy, kCg

    def _residual(self, q, yb, g: float, x1: float, v1: float, jacobian: bool):
        """Stage residuals r [N] at q = (w, up, uf, fR, gC), their Jacobian (or None) and the size [N] of
        each residual: the sum of the magnitudes of its terms, including a term's change over the rounding of
        the positions and velocities it takes (the mount's kM |x1| and kM |y|), so that ``_RESOLUTION`` times
        it is what double precision can resolve of that residual."""
        w, up, uf, fR, gC = q
        a = self.a
        y = yb[0] + g * w
        kR, kRy, kRf, kC, kCy, kCg = self.stiffness(y, fR, gC)
        uR, uC = w - up, -w + a * up - uf
        ip, jf = self.fp.segment(up), self.ff.segment(uf)
        ds = self.damping_scale
        sp, sf = ds * self.fp.slope[ip], ds * self.ff.slope[jf]
        ap, af = ds * self.fp.intercept[ip], ds * self.ff.intercept[jf]
        fr = dfr = 0.0
        if self.ffr:
            th = math.tanh(w / self.v_eps)
            fr, dfr = self.ffr * th, self.ffr * (1.0 - th * th) / self.v_eps
        fm, fe, fd = self.mount(x1 - y, v1 - w)
        r4, dr4 = fR - gC + fr - fm, g * fe + fd + dfr
        r = [fR - yb[1] - g * kR * uR,
             gC - yb[2] - g * kC * uC,
             fR - a * gC - (ap + sp * up),
             gC - (af + sf * uf),
             r4]
        size = [abs(fR) + abs(yb[1]) + g * kR * (abs(w) + abs(up)),
                abs(gC) + abs(yb[2]) + g * kC * (abs(w) + a * abs(up) + abs(uf)),
                abs(fR) + a * abs(gC) + abs(ap) + abs(sp * up),
                abs(gC) + abs(af) + abs(sf * uf),
                abs(fR) + abs(gC) + abs(fr) + dfr * abs(w) + abs(fm) + abs(fe) * (abs(x1) + abs(y))
                + abs(fd) * (abs(v1) + abs(w))]
        if not jacobian:
            return r, None, size
        jac = [[-g * (kR + g * kRy * uR), g * kR, 0.0, 1.0 - g * kRf * uR, 0.0],
               [-g * (-kC + g * kCy * uC), -g * kC * a, g * kC, 0.0, 1.0 - g * kCg * uC],
               [0.0, -sp, 0.0, 1.0, -a],
               [0.0, 0.0, -sf, 0.0, 1.0],
               [dr4, 0.0, 0.0, 1.0, -1.0]]
        return r, jac, size

    def _tolerance(self, size: list[float], n: int) -> float:
        """Tolerance [N] on the sum of the first n |residuals|: ``_TC_TOL`` of the force scale, or what double
        precision resolves of them (``_RESOLUTION`` times their sizes) where that is more (a stiff mount far from
        the stroke origin on a small damper)."""
        return max(self._tol, _RESOLUTION * _abs_sum(size, n))

    def _newton(self, q: list[float], held: int, yb, g: float, x1: float, v1: float):
        """Newton's method on the stage residuals for the unknowns q[held:] (the first ``held`` stay
        as given), on as many residuals as unknowns: full steps first (exact within the valves'
        linear pieces, usually done in 2-4), then, if the pieces keep changing, a backtracking line
        search on the sum of those |residuals| [N]. Returns (q, Jacobian at q, residual sum, its tolerance
        at q (``_tolerance``) [N], singular: True when a Jacobian could not be solved)."""
        n = 5 - held
        r, jac, size = self._residual(q, yb, g, x1, v1, True)
        rn, tol = _abs_sum(r, n), self._tolerance(size, n)
        for it in range(_TC_MAX_NEWTON):
            if rn <= tol:
                break
            d = _solve_stage(jac, r) if held == 0 else _solve([row[held:] for row in jac[:n]], r[:n])
            if d is None:
                return q, jac, rn, tol, True
            if it < _TC_PLAIN:  # plain Newton
                q = q[:held] + [qi - di for qi, di in zip(q[held:], d)]
                r, jac, size = self._residual(q, yb, g, x1, v1, True)
                rn, tol = _abs_sum(r, n), self._tolerance(size, n)
                continue
            lam, accepted = 1.0, False  # then damped: backtracking on the sum of |residuals|
            for _ in range(_TC_MAX_HALVINGS):
                qt = q[:held] + [qi - lam * di for qi, di in zip(q[held:], d)]
                rt, _, _ = self._residual(qt, yb, g, x1, v1, False)
                rnt = _abs_sum(rt, n)
                if rnt < rn:
                    accepted = True
                    break
                lam *= 0.5
            if not accepted:
                break
            q, rn = qt, rnt
            r, jac, size = self._residual(q, yb, g, x1, v1, True)
            tol = self._tolerance(size, n)
        return q, jac, rn, tol, False

    def stage(self, yb, g: float, x1: float, v1: float) -> list[float]:
        """Solve y = yb + g f(y) for the two-chamber model (x1 [m], v1 [m/s] at the stage time).

        Unknowns: piston velocity w, valve rates up, uf and the chamber forces. Newton's method
        (``_newton``), started from the valve rates of the base point and the piston velocity at
        frozen chamber forces: with a free play, that of the mount linearised at the last piston velocity
        (the mount's force is a kink smoothed over PLAY_SMOOTHING: the engaged mount's guess, far off inside
        the dead band, sent the iteration to its line search and nested fallback at every crossing, 10 x
        the cost of a simulation without the gap)."""
        fb = yb[1] - yb[2] + (self.ffr * math.tanh(yb[6] / self.v_eps) if self.ffr else 0.0)
        if not self.gap:
            w0 = (self.cM * v1 - fb + self.kM * (x1 - yb[0])) / (self.cM + self.kM * g)
        else:
            wp = yb[6]
            fm, fe, fd = self.mount(x1 - (yb[0] + g * wp), v1 - wp)
            den = g * fe + fd
            w0 = wp + (fm - fb) / den if den > _TC_DISENGAGED * (self.cM + self.kM * g) else wp
        q, _, rn, tol, singular = self._newton([w0, yb[4], yb[5], yb[1], yb[2]], 0, yb, g, x1, v1)
        if singular:
            raise ConvergenceError("two-chamber stage: singular Jacobian")
        if not rn <= tol:  # e.g. a steep seal friction at a reversal: the nested solve
            q = self._stage_nested(yb, g, x1, v1, w0, (rn, tol))
        w, up, uf, fR, gC = q
        return [yb[0] + g * w, fR, gC, yb[3], up, uf, w]

    def _valves_given_w(self, w: float, p4: list[float], yb, g: float, x1: float, v1: float):
        """The chamber and valve equations (residuals 0-3) solved for (up, uf, fR, gC) at the piston
        velocity w [m/s], from p4; returns (p4, d(fR - gC)/dw [N s/m], |r0..r3| sum, its tolerance [N]) -- the
        same Newton iteration as ``stage`` with w held; the derivative by implicit differentiation."""
        q, jac, rn, tol, _ = self._newton([w, *p4], 1, yb, g, x1, v1)
        dq = _solve([row[1:] for row in jac[:4]], [-row[0] for row in jac[:4]])
        dfw = 0.0 if dq is None else dq[2] - dq[3]
        return q[1:], dfw, rn, tol

    def _stage_nested(self, yb, g: float, x1: float, v1: float, w0: float, stalled: tuple) -> list[float]:
        """Fallback of ``stage``: a safeguarded Newton iteration (bisection once bracketed) on the
        mount balance, residual 4, which increases with the piston velocity w when the chamber and
        valve equations are solved for each w (``_valves_given_w``). Robust where the joint Newton
        iteration is not (a steep seal friction tanh(w / v_eps) at a reversal). ``stalled``: the joint
        iteration's residual sum and tolerance [N], for the message when this fails too."""
        p4 = [yb[4], yb[5], yb[1], yb[2]]
        w, lo, hi = w0, -math.inf, math.inf
        for _ in range(_TC_MAX_NESTED):
            p4, dfw, rn4, tol4 = self._valves_given_w(w, p4, yb, g, x1, v1)
            if not rn4 <= tol4:
                break
            r, _, size = self._residual([w, *p4], yb, g, x1, v1, False)
            if abs(r[4]) <= self._tolerance(size, 5):
                return [w, *p4]
            fr_slope = 0.0
            if self.ffr:
                th = math.tanh(w / self.v_eps)
                fr_slope = self.ffr * (1.0 - th * th) / self.v_eps
            _, fe, fd = self.mount(x1 - (yb[0] + g * w), v1 - w)
            slope = dfw + fr_slope + g * fe + fd
            if r[4] > 0.0:
                hi = w
            else:
                lo = w
            wn = w - r[4] / slope
            if not lo < wn < hi:
                if math.isinf(lo) or math.isinf(hi):
                    wn = w - 2.0 * r[4] / slope  # outside the one known side: a longer step
                else:
                    wn = 0.5 * (lo + hi)
            if not math.isinf(lo) and not math.isinf(hi) and hi - lo <= _RESOLUTION * max(abs(lo), abs(hi)):
                break  # the bracket is a few units in the last place of w wide
            w = wn
        raise ConvergenceError(f"two-chamber stage: Newton stalled at a residual of {stalled[0]:.3g} N and the "
                               f"nested solve did not converge either (tolerance {stalled[1]:.3g} N)")

    def diagnostics(self, y, x1: float, v1: float) -> dict[str, float]:
        """Mount elongation [m], chamber forces [N] and valve rates [m/s] of the state y."""
        return {"mount_elongation": x1 - y[0], "rebound_chamber_force": y[1], "compression_chamber_force": y[2],
                "piston_valve_rate": y[4], "foot_valve_rate": y[5]}


_MODELS = {"lumped": LumpedModel, "maxwell": MaxwellModel, "maxwell_table": MaxwellTableModel,
           "twochamber": TwoChamberModel}


def make_model(kind: str, params: dict[str, float] | None = None):
    """Model instance of ``kind`` ('lumped', 'maxwell', 'maxwell_table', 'twochamber') with ``params`` (SI)."""
    try:
        cls = _MODELS[kind]
    except KeyError:
        raise ValueError(f"unknown model '{kind}', expected one of {sorted(_MODELS)}") from None
    return cls(params)
