/* Two-chamber lumped hydraulic form (issue 12 research prototype), massless.

   actuator x1 --[mounts kM, cM]-- piston (hydraulic displacement y) ; chambers in force units:
     fR = Aa pR  (rebound chamber, gauge vs reservoir),  gC = Ap pC (compression chamber)
     fR' = kR (y' - up)                 kR = beta Aa^2 / V_R     up: piston-valve flow / Aa
     gC' = kC (-y' + a up - uf)         kC = beta Ap^2 / V_C     uf: foot-valve flow / Ap, a = Aa/Ap
     piston valve:  fR - a gC = Fp(up)  (up > 0: rebound damping table; up < 0: check, slope cchk)
     foot valve:    gC = Ff(uf)         (uf > 0: compression damping; uf < 0: intake check, slope cchk)
     F = fR - gC = kM eM + cM eM'  (tension +), eM = x1 - y
   Fp, Ff are piecewise-linear (built by the caller, passing through 0, monotone).
   Optional: kR, kC pressure-stiffening (ignored here).  Implicit Euler, Newton in (dy, up, uf)
   with a backtracking line search on the residual norm. */
#include <math.h>

typedef struct { int n; const double *x; const double *f; } Tab;

static double tab(const Tab *t, double u, double *slope) {
  int n = t->n; const double *x = t->x, *f = t->f;
  if (u <= x[0]) { double s = (f[1]-f[0])/(x[1]-x[0]); *slope = s; return f[0] + s*(u - x[0]); }
  if (u >= x[n-1]) { double s = (f[n-1]-f[n-2])/(x[n-1]-x[n-2]); *slope = s; return f[n-1] + s*(u - x[n-1]); }
  int lo = 0, hi = n - 1;
  while (hi - lo > 1) { int m = (lo + hi) / 2; if (x[m] <= u) lo = m; else hi = m; }
  double s = (f[lo+1]-f[lo])/(x[lo+1]-x[lo]); *slope = s; return f[lo] + s*(u - x[lo]);
}

typedef struct {
  Tab fp, ff; double kR, kC, a, kM, cM, h, LR, LC, kRy, kCy, air, fres, ffric, veps, fr_last;
  double fR0, gC0, eM0, y0;
} TC;

static void resid(const TC *c, double x1, const double *q, double *r, double J[3][3]) {
  double dy = q[0], up = q[1], uf = q[2], h = c->h, sp, sf;
  double fR = c->fR0 + c->kRy * (dy - h * up);
  double gC = c->gC0 + c->kCy * (-dy + h * c->a * up - h * uf);
  double Fp = tab(&c->fp, up, &sp), Ff = tab(&c->ff, uf, &sf);
  double eM = x1 - (c->y0 + dy);
  double Fm = c->kM * eM + c->cM * (eM - c->eM0) / h;
  r[0] = fR - c->a * gC - Fp;
  r[1] = gC - Ff;
  double fr = 0.0, dfr = 0.0;
  if (c->ffric > 0) { double th = tanh(dy / h / c->veps); fr = c->ffric * th; dfr = c->ffric * (1 - th * th) / (h * c->veps); }
  r[2] = fR - gC + fr - Fm;
  if (J) {
    double dfR[3] = {c->kRy, -c->kRy * h, 0.0};
    double dgC[3] = {-c->kCy, c->kCy * h * c->a, -c->kCy * h};
    for (int j = 0; j < 3; j++) {
      J[0][j] = dfR[j] - c->a * dgC[j];
      J[1][j] = dgC[j];
      J[2][j] = dfR[j] - dgC[j];
    }
    J[0][1] -= sp; J[1][2] -= sf; J[2][0] += c->kM + c->cM / h + dfr;
  }
}

static int solve3(double A[3][3], const double *b, double *x) {
  double M[3][4];
  for (int i = 0; i < 3; i++) { for (int j = 0; j < 3; j++) M[i][j] = A[i][j]; M[i][3] = b[i]; }
  for (int k = 0; k < 3; k++) {
    int p = k; for (int i = k + 1; i < 3; i++) if (fabs(M[i][k]) > fabs(M[p][k])) p = i;
    if (fabs(M[p][k]) < 1e-300) return 1;
    if (p != k) for (int j = 0; j < 4; j++) { double t = M[k][j]; M[k][j] = M[p][j]; M[p][j] = t; }
    for (int i = k + 1; i < 3; i++) { double f = M[i][k] / M[k][k]; for (int j = k; j < 4; j++) M[i][j] -= f * M[k][j]; }
  }
  for (int i = 2; i >= 0; i--) { double s = M[i][3]; for (int j = i + 1; j < 3; j++) s -= M[i][j] * x[j]; x[i] = s / M[i][i]; }
  return 0;
}

static double clipd(double d) { return d < 0.05 ? 0.05 : d; }

static int step(TC *c, double x1, double *q) {
  /* chamber stiffness at the current piston position (volumes V_R0 - Aa y, V_C0 + Ap y):
     LR, LC = V_R0/Aa, V_C0/Ap [m] (0: position-independent) */
  c->kRy = c->LR > 0 ? c->kR / clipd(1.0 - c->y0 / c->LR) : c->kR;
  c->kCy = c->LC > 0 ? c->kC / clipd(1.0 + c->y0 / c->LC) : c->kC;
  if (c->air > 0) {  /* entrained air: k = k_liquid / (1 + air (p / p_res)^-1.714), p / p_res = 1 + gauge force / (A p_res) */
    double rR = 1.0 + c->fR0 / (c->a * c->fres), rC = 1.0 + c->gC0 / c->fres;
    rR = rR < 0.05 ? 0.05 : rR; rC = rC < 0.05 ? 0.05 : rC;
    c->kRy /= 1.0 + c->air * pow(rR, -1.714);
    c->kCy /= 1.0 + c->air * pow(rC, -1.714);
  }
  double r[3], J[3][3], d[3], rn, qt[3], rt[3];
  resid(c, x1, q, r, J);
  rn = fabs(r[0]) + fabs(r[1]) + fabs(r[2]);
  for (int it = 0; it < 60; it++) {
    if (rn < 1e-6) break;
    if (solve3(J, r, d)) return 1;
    double lam = 1.0; int ok = 0;
    for (int ls = 0; ls < 40; ls++) {
      for (int i = 0; i < 3; i++) qt[i] = q[i] - lam * d[i];
      resid(c, x1, qt, rt, 0);
      double rnt = fabs(rt[0]) + fabs(rt[1]) + fabs(rt[2]);
      if (rnt < rn) { for (int i = 0; i < 3; i++) q[i] = qt[i]; rn = rnt; ok = 1; break; }
      lam *= 0.5;
    }
    if (!ok) break;
    resid(c, x1, q, r, J);
  }
  int failed = rn > 1.0;  /* N: a step whose equations are not met to 1 N is counted (and still taken) */
  double h = c->h, dy = q[0], up = q[1], uf = q[2];
  c->fR0 = c->fR0 + c->kRy * (dy - h * up);
  c->gC0 = c->gC0 + c->kCy * (-dy + h * c->a * up - h * uf);
  c->y0 += dy;
  c->eM0 = x1 - c->y0;
  c->fr_last = c->ffric > 0 ? c->ffric * tanh(dy / h / c->veps) : 0.0;
  return failed;
}

/* Friction case (ffric > 0): nested solve. For a given piston increment dy, (up, uf) solve the two valve
   equations (the gradient of a concave piecewise-quadratic function: Newton on the pieces, damped);
   the mount balance r2(dy) = fR - gC + fr(dy) - Fm(dy) is increasing in dy: safeguarded Newton/bisection. */
static void vres(const TC *c, double dy, double up, double uf, double *r0, double *r1, double *J) {
  double h = c->h, a = c->a, sp, sf;
  double fR = c->fR0 + c->kRy * (dy - h * up);
  double gC = c->gC0 + c->kCy * (-dy + h * a * up - h * uf);
  *r0 = fR - a * gC - tab(&c->fp, up, &sp);
  *r1 = gC - tab(&c->ff, uf, &sf);
  J[0] = -c->kRy * h - a * a * c->kCy * h - sp; J[1] = a * c->kCy * h;
  J[2] = a * c->kCy * h; J[3] = -c->kCy * h - sf;
}

static double valves_given_dy(const TC *c, double dy, double *uq, double *dr2) {
  double h = c->h, a = c->a, up = uq[0], uf = uq[1], r0, r1, J[4];
  vres(c, dy, up, uf, &r0, &r1, J);
  double rn = fabs(r0) + fabs(r1);
  for (int it = 0; it < 100 && rn > 1e-7; it++) {
    double det = J[0] * J[3] - J[1] * J[2];
    double d0 = (r0 * J[3] - r1 * J[1]) / det, d1 = (J[0] * r1 - J[2] * r0) / det;
    double lam = 1.0; int ok = 0;
    for (int ls = 0; ls < 50; ls++) {
      double t0, t1, Jt[4];
      vres(c, dy, up - lam * d0, uf - lam * d1, &t0, &t1, Jt);
      if (fabs(t0) + fabs(t1) < rn) { up -= lam * d0; uf -= lam * d1; r0 = t0; r1 = t1; rn = fabs(t0) + fabs(t1);
        for (int k = 0; k < 4; k++) J[k] = Jt[k]; ok = 1; break; }
      lam *= 0.5;
    }
    if (!ok) break;
  }
  uq[0] = up; uq[1] = uf;
  /* d(fR - gC)/d dy with (up, uf) re-solved: implicit differentiation of the 2x2 system */
  double sp, sf; tab(&c->fp, up, &sp); tab(&c->ff, uf, &sf);
  double j00 = -c->kRy * h - a * a * c->kCy * h - sp, j01 = a * c->kCy * h;
  double j10 = a * c->kCy * h, j11 = -c->kCy * h - sf;
  double b0 = -(c->kRy + a * c->kCy), b1 = c->kCy;   /* -d r / d dy */
  double det = j00 * j11 - j01 * j10;
  double dup = (b0 * j11 - b1 * j01) / det, duf = (j00 * b1 - j10 * b0) / det;
  double dfR = c->kRy * (1 - h * dup), dgC = c->kCy * (-1 + h * a * dup - h * duf);
  *dr2 = dfR - dgC;
  double fR = c->fR0 + c->kRy * (dy - h * up);
  double gC = c->gC0 + c->kCy * (-dy + h * a * up - h * uf);
  return fR - gC;
}

static int step_friction(TC *c, double x1, double *q) {
  double h = c->h, uq[2] = {q[1], q[2]}, dy = q[0], lo = 0, hi = 0, r2 = 0;
  int hl = 0, hh = 0;
  for (int it = 0; it < 200; it++) {
    double dFh, Fh = valves_given_dy(c, dy, uq, &dFh);
    double th = tanh(dy / h / c->veps);
    double eM = x1 - (c->y0 + dy);
    double Fm = c->kM * eM + c->cM * (eM - c->eM0) / h;
    r2 = Fh + c->ffric * th - Fm;
    double d = dFh + c->ffric * (1 - th * th) / (h * c->veps) + c->kM + c->cM / h;
    if (r2 > 0) { hi = dy; hh = 1; } else { lo = dy; hl = 1; }
    if (fabs(r2) < 1e-6) break;
    double dn = dy - r2 / d;
    if (hl && hh && !(dn > lo && dn < hi)) dn = 0.5 * (lo + hi);
    if (hl && hh && hi - lo < 1e-18) break;
    dy = dn;
  }
  q[0] = dy; q[1] = uq[0]; q[2] = uq[1];
  double up = q[1], uf = q[2];
  c->fR0 = c->fR0 + c->kRy * (dy - h * up);
  c->gC0 = c->gC0 + c->kCy * (-dy + h * c->a * up - h * uf);
  c->y0 += dy;
  c->eM0 = x1 - c->y0;
  c->fr_last = c->ffric * tanh(dy / h / c->veps);
  return fabs(r2) > 1.0;
}

int simulate_tc(int n, const double *x, double dt, int sub,
                int np, const double *fpx, const double *fpf, int nf, const double *ffx, const double *fff,
                double kR, double kC, double a, double kM, double cM, double LR, double LC, double air, double fres, double ffric, double veps, double *out, int *fails) {
  TC c; c.fp.n = np; c.fp.x = fpx; c.fp.f = fpf; c.ff.n = nf; c.ff.x = ffx; c.ff.f = fff;
  c.kR = kR; c.kC = kC; c.LR = LR; c.LC = LC; c.air = air; c.fres = fres; c.ffric = ffric; c.veps = veps; c.fr_last = 0.0; c.kRy = kR; c.kCy = kC; c.a = a; c.kM = kM; c.cM = cM; c.h = dt / sub;
  c.fR0 = 0.0; c.gC0 = 0.0; c.y0 = x[0]; c.eM0 = 0.0;
  double q[3] = {0.0, 0.0, 0.0}, xprev = x[0];
  *fails = 0;
  out[0] = 0.0;
  for (int k = 1; k < n; k++) {
    for (int j = 1; j <= sub; j++) {
      double x1 = x[k-1] + (x[k] - x[k-1]) * (double)j / sub;
      q[0] = x1 - xprev;  /* guess: the piston follows the actuator */
      xprev = x1;
      int bad;
      if (c.ffric > 0) {
        c.kRy = c.LR > 0 ? c.kR / clipd(1.0 - c.y0 / c.LR) : c.kR;
        c.kCy = c.LC > 0 ? c.kC / clipd(1.0 + c.y0 / c.LC) : c.kC;
        if (c.air > 0) {
          double rR = 1.0 + c.fR0 / (c.a * c.fres), rC = 1.0 + c.gC0 / c.fres;
          rR = rR < 0.05 ? 0.05 : rR; rC = rC < 0.05 ? 0.05 : rC;
          c.kRy /= 1.0 + c.air * pow(rR, -1.714);
          c.kCy /= 1.0 + c.air * pow(rC, -1.714);
        }
        bad = step_friction(&c, x1, q);
      } else bad = step(&c, x1, q);
      if (bad) { (*fails)++; if (*fails > 1000) return 1; }
    }
    /* output force: mount force F = fR - gC (equal to kM eM + cM eM' at the solution) */
    out[k] = c.fR0 - c.gC0 + c.fr_last;
  }
  return 0;
}
