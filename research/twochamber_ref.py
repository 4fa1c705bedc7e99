"""Readable Python reference of the two-chamber lumped form (same equations and scheme as
research/c/twochamber.c; slow, for porting into damper_fmu and for tests).

Chain and sign convention as damper_fmu.models (x extension +, forces tension +):

    actuator x1 --[silent blocks kM, cM (both in series)]-- piston y --| rebound chamber R  |-- frame
                                                                        | compression chamb. C|
                                                                        | reservoir (p const) |

Chamber pressures in force units (gauge against the reservoir): fR = Aa pR, gC = Ap pC; a = Aa/Ap.

    fR' = kR(y, fR) (y' - up)            piston-valve flow / Aa = up
    gC' = kC(y, gC) (-y' + a up - uf)    foot-valve flow / Ap = uf
    fR - a gC = Fp(up)    piston valve: up > 0 rebound damping (the Fc,O table's rebound half);
                          up < 0 the piston check (slope CCHK)
    gC = Ff(uf)           foot valve: uf > 0 compression damping, Ff(u) = -Fc,O(-u/(1-a))/(1-a) (the
                          table's compression half, so that the steady compression force is Fc,O(v));
                          uf < 0 the intake check (slope CCHK)
    F = fR - gC + Ff tanh(y'/v_eps) = kM eM + cM eM',  eM = x1 - y  (measured force, tension +;
        Ff: optional seal friction between rod and cylinder, option 'friction')
    plus kgas (x1 - x1(0)): reservoir gas spring on the rod, zero where the rig tared (option 'gas';
        added to the output, as research/twochamber.sim_signals does)

Chamber stiffness with position and entrained air (options 'pos', 'air'):
    kR(y, fR) = kR / (1 - y/LR) / (1 + air (1 + fR/(a fres))^-1.714)
    kC(y, gC) = kC / (1 + y/LC) / (1 + air (1 + gC/fres)^-1.714)
LR = V_R0/Aa, LC = V_C0/Ap: chamber lengths at mid-stroke [m]; air: softening of the oil at reservoir
pressure (a0 beta_l / (n p_atm) (p_atm/p_res)^(1+1/n)) [-]; fres = Ap p_res [N]; exponent 1 + 1/1.4.
Implicit Euler with the stiffness frozen over a step; Newton in (dy, up, uf) with backtracking."""
from __future__ import annotations

import numpy as np

from research.twochamber import CCHK, valve_tables


def _pwl(x, f, u):
    """value and slope of the piecewise-linear table (x, f) at u, linear extrapolation"""
    n = len(x)
    if u <= x[0]:
        i = 0
    elif u >= x[-1]:
        i = n - 2
    else:
        i = int(np.searchsorted(x, u, side="right")) - 1
    s = (f[i + 1] - f[i]) / (x[i + 1] - x[i])
    return f[i] + s * (u - x[i]), s


class TwoChamber:
    def __init__(self, prm: dict):
        self.p = dict(prm)
        self.fpx, self.fpf, self.ffx, self.fff = valve_tables(prm["fc_x"], prm["fc_f"], prm["a"], prm.get("cchk", CCHK),
                                                              prm.get("crack_p", 0.0), prm.get("crack_f", 0.0))

    def stiffness(self, y, fR, gC):
        p = self.p
        kR, kC = p["kR"], p["kC"]
        if p.get("LR", 0.0) > 0:
            kR /= max(1.0 - y / p["LR"], 0.05)
            kC /= max(1.0 + y / p["LC"], 0.05)
        if p.get("air", 0.0) > 0:
            kR /= 1.0 + p["air"] * max(1.0 + fR / (p["a"] * p["fres"]), 0.05) ** -1.714
            kC /= 1.0 + p["air"] * max(1.0 + gC / p["fres"], 0.05) ** -1.714
        return kR, kC

    def simulate(self, x, dt, sub=4):
        p, a = self.p, self.p["a"]
        kM, cM, h = p["kM"], p["cM"], dt / sub
        ffr, veps, kgas = p.get("ffric", 0.0), p.get("veps", 5e-4), p.get("kgas", 0.0)
        fR = gC = eM = 0.0
        y = xprev = float(x[0])
        q = np.zeros(3)
        out = np.zeros(len(x))
        for k in range(1, len(x)):
            for j in range(1, sub + 1):
                x1 = x[k - 1] + (x[k] - x[k - 1]) * j / sub
                kR, kC = self.stiffness(y, fR, gC)
                q[0] = x1 - xprev
                xprev = x1

                def res(q):
                    dy, up, uf = q
                    fRn = fR + kR * (dy - h * up)
                    gCn = gC + kC * (-dy + h * a * up - h * uf)
                    Fp, sp = _pwl(self.fpx, self.fpf, up)
                    Ff, sf = _pwl(self.ffx, self.fff, uf)
                    eMn = x1 - (y + dy)
                    Fm = kM * eMn + cM * (eMn - eM) / h
                    th = np.tanh(dy / h / veps) if ffr else 0.0
                    r = np.array([fRn - a * gCn - Fp, gCn - Ff, fRn - gCn + ffr * th - Fm])
                    dfR = np.array([kR, -kR * h, 0.0])
                    dgC = np.array([-kC, kC * h * a, -kC * h])
                    J = np.vstack([dfR - a * dgC, dgC, dfR - dgC])
                    J[0, 1] -= sp
                    J[1, 2] -= sf
                    J[2, 0] += kM + cM / h + (ffr * (1 - th * th) / (h * veps) if ffr else 0.0)
                    return r, J

                r, J = res(q)
                rn = np.abs(r).sum()
                for _ in range(60):
                    if rn < 1e-6:
                        break
                    d = np.linalg.solve(J, r)
                    lam = 1.0
                    for _ in range(40):
                        qt = q - lam * d
                        rt, Jt = res(qt)
                        if np.abs(rt).sum() < rn:
                            q, r, J, rn = qt, rt, Jt, np.abs(rt).sum()
                            break
                        lam *= 0.5
                    else:
                        break
                dy, up, uf = q
                fR += kR * (dy - h * up)
                gC += kC * (-dy + h * a * up - h * uf)
                y += dy
                eM = x1 - y
                fr = ffr * np.tanh(dy / h / veps) if ffr else 0.0
            out[k] = fR - gC + fr + kgas * (x[k] - x[0])
        return out


if __name__ == "__main__":  # the reference and the C prototype agree
    import json
    from research.twochamber import simulate

    prm = json.load(open("/tmp/form/tc_results_s1.json"))["tc_pos_air_x2"]["params"]
    prm = {k: (np.array(v) if isinstance(v, list) else v) for k, v in prm.items()}
    t = np.arange(0, 2.0, 1e-3)
    x = 0.02 * np.sin(2 * np.pi * 0.7 * t) + 0.001 * np.sin(2 * np.pi * 6 * t)
    prm["ffric"] = 120.0
    fc, _ = simulate(x, 1e-3, prm, 4)
    fc = fc + prm.get("kgas", 0.0) * (x - x[0])
    fp = TwoChamber(prm).simulate(x, 1e-3, 4)
    print("max |C - Python| =", np.abs(fc - fp).max(), "N of peak", np.abs(fc).max())
