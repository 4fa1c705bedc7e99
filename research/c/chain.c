/* Massless lumped damper chain with an optional extra branch (issue 12 form research).

   actuator x1 --[mounts: kM, cM (both silent blocks in series)]-- y --[hydraulic part]-- frame

   hydraulic part: damping table Fc(z') in series with elastic table Fk(e), y = z + e, plus
   an optional branch B:
     attach 0: B(e) parallel to Fk only    (F_h = Fk(e) + B(e) = Fc(z'))
     attach 1: B(y) parallel to Fk + Fc   (F_h = Fk(e) + B(y), Fk(e) = Fc(z'))
   branch kind 0: none; 1: linear Maxwell (k2, c2); 2: Jenkins elasto-plastic (k2, Fy+, Fy-);
               3: Maxwell with its own table-free dashpot c2 and Jenkins limit (k2, c2, Fy)  [k2 (q-w), c2 w' = f]
   kind 4: direction-switched stiffness (Fk scaled by 1 + a for a window after reversal) -- not used.
   Implicit Euler on a sub-step grid, nested safeguarded Newton (all functions monotone).
   Output: actuator force F = kM eM + cM eM' at every input sample. */
#include <math.h>
#include <stddef.h>

typedef struct { int n; const double *x; const double *f; } Tab;  /* F(0)=0 inserted by caller */

static double tab(const Tab *t, double u, double *slope) {
  int n = t->n; const double *x = t->x, *f = t->f;
  int i;
  if (u <= x[0]) { double s = (f[1]-f[0])/(x[1]-x[0]); *slope = s; return f[0] + s*(u - x[0]); }
  if (u >= x[n-1]) { double s = (f[n-1]-f[n-2])/(x[n-1]-x[n-2]); *slope = s; return f[n-1] + s*(u - x[n-1]); }
  int lo = 0, hi = n - 1;
  while (hi - lo > 1) { int m = (lo + hi) / 2; if (x[m] <= u) lo = m; else hi = m; }
  i = lo;
  { double s = (f[i+1]-f[i])/(x[i+1]-x[i]); *slope = s; return f[i] + s*(u - x[i]); }
}

typedef struct {
  Tab fc, fk; double kM, cM;
  int kind, attach; double k2, c2, fyp, fyn;
  double h;
  /* position-dependent stiffness of the elastic element (kind-independent option):
     scaled elongation ee: ee' = s e', s = 1/(1 - y/LR) for ee >= 0, 1/(1 + y/LC) for ee < 0 (0: off) */
  double LR, LC, s_pos, ee0, e0;
  /* state */
  double z0, w0, eM0;
} Chain;

static double fk_eval(const Chain *c, double e, double *slope) {
  if (c->LR <= 0) return tab(&c->fk, e, slope);
  double ee = c->ee0 + c->s_pos * (e - c->e0), s;
  double f = tab(&c->fk, ee, &s);
  *slope = s * c->s_pos;
  return f;
}

/* branch force at q with previous internal state w0: returns force, slope, new w */
static double branch(const Chain *c, double q, double *slope, double *wnew) {
  double f, s;
  switch (c->kind) {
  case 1: { double a = c->c2 / c->h; double w = (a * c->w0 + c->k2 * q) / (a + c->k2);
            f = c->k2 * (q - w); s = c->k2 * a / (a + c->k2); *wnew = w; break; }
  case 2: { f = c->k2 * (q - c->w0); s = c->k2;
            if (f > c->fyp) { f = c->fyp; s = 0.0; } else if (f < -c->fyn) { f = -c->fyn; s = 0.0; }
            *wnew = q - f / c->k2; break; }
  case 3: { /* Maxwell (k2, c2) then clip at +-Fy (check valve: viscous + cracking limit) */
            double a = c->c2 / c->h; double w = (a * c->w0 + c->k2 * q) / (a + c->k2);
            f = c->k2 * (q - w); s = c->k2 * a / (a + c->k2);
            if (f > c->fyp) { f = c->fyp; s = 0.0; w = q - f / c->k2; }
            else if (f < -c->fyn) { f = -c->fyn; s = 0.0; w = q - f / c->k2; }
            *wnew = w; break; }
  default: f = 0.0; s = 0.0; *wnew = c->w0;
  }
  *slope = s; return f;
}

/* inner: given y, solve g(e) = A(e) - Fc((y - e - z0)/h) = 0; return F_h and dF_h/dy, e, w */
static double inner(const Chain *c, double y, double e_guess, double *dFdy, double *e_out, double *w_out) {
  double h = c->h, e = e_guess, lo = -1.0, hi = 1.0; int have_lo = 0, have_hi = 0;
  double A = 0, As = 0, fcs = 0, g = 0, bs = 0, w = c->w0, fks = 0;
  for (int it = 0; it < 200; it++) {
    double fk = fk_eval(c, e, &fks);
    double b = 0.0; bs = 0.0; w = c->w0;
    if (c->attach == 0 && c->kind) b = branch(c, e, &bs, &w);
    A = fk + b; As = fks + bs;
    double fc = tab(&c->fc, (y - e - c->z0) / h, &fcs);
    g = A - fc;
    double dg = As + fcs / h;
    if (g > 0) { hi = e; have_hi = 1; } else { lo = e; have_lo = 1; }
    double en = e - g / dg;
    if (fabs(g) < 1e-9 * (1.0 + fabs(A))) break;
    if (have_lo && have_hi) { if (!(en > lo && en < hi)) en = 0.5 * (lo + hi); if (hi - lo < 1e-16) break; }
    if (en == e) break;
    e = en;
  }
  double dedy = (fcs / h) / (As + fcs / h);
  double Fh, dF;
  if (c->attach == 0 || !c->kind) { Fh = A; dF = As * dedy; }
  else { double bsy; Fh = A + branch(c, y, &bsy, &w); dF = As * dedy + bsy; }
  *dFdy = dF; *e_out = e; *w_out = w;
  return Fh;
}

/* one step to actuator position x1; returns F */
static double clipd(double d) { return d < 0.05 ? 0.05 : d; }

static double step(Chain *c, double x1, double *y_io, double *e_io) {
  if (c->LR > 0) c->s_pos = c->ee0 >= 0 ? 1.0 / clipd(1.0 - *y_io / c->LR) : 1.0 / clipd(1.0 + *y_io / c->LC);
  double y = *y_io, e = *e_io, lo = 0, hi = 0; int have_lo = 0, have_hi = 0;
  double a = c->cM / c->h, F = 0, w = c->w0, ee = e;
  for (int it = 0; it < 200; it++) {
    double dFh, Fh = inner(c, y, e, &dFh, &ee, &w);
    double eM = x1 - y;
    F = c->kM * eM + a * (eM - c->eM0);
    double R = Fh - F, dR = dFh + c->kM + a;
    if (R > 0) { hi = y; have_hi = 1; } else { lo = y; have_lo = 1; }
    double yn = y - R / dR;
    if (fabs(R) < 1e-7 * (1.0 + fabs(F))) { e = ee; break; }
    if (have_lo && have_hi) { if (!(yn > lo && yn < hi)) yn = 0.5 * (lo + hi); if (hi - lo < 1e-16) { e = ee; break; } }
    e = ee;
    if (yn == y) break;
    y = yn;
  }
  /* commit */
  if (c->LR > 0) { c->ee0 = c->ee0 + c->s_pos * (e - c->e0); c->e0 = e; }
  c->z0 = y - e; c->w0 = w; c->eM0 = x1 - y;
  *y_io = y; *e_io = e;
  return F;
}

/* simulate: n samples of x (uniform, dt), sub substeps with linear interpolation; out force.
   fcx/fcf: damping table incl. (0,0); fkx/fkf: elastic table incl. (0,0). returns 0 ok */
int simulate(int n, const double *x, double dt, int sub,
             int nfc, const double *fcx, const double *fcf, int nfk, const double *fkx, const double *fkf,
             double kM, double cM, int kind, int attach, double k2, double c2, double fyp, double fyn,
             double LR, double LC, double *out) {
  Chain c; c.fc.n = nfc; c.fc.x = fcx; c.fc.f = fcf; c.fk.n = nfk; c.fk.x = fkx; c.fk.f = fkf;
  c.kM = kM; c.cM = cM; c.kind = kind; c.attach = attach; c.k2 = k2; c.c2 = c2; c.fyp = fyp; c.fyn = fyn;
  c.h = dt / sub; c.LR = LR; c.LC = LC; c.s_pos = 1.0; c.ee0 = 0.0; c.e0 = 0.0;
  /* force-free start: mounts and springs unloaded, dashpot carries the offset */
  c.z0 = x[0]; c.w0 = (attach == 1) ? x[0] : 0.0; c.eM0 = 0.0;
  double y = x[0], e = 0.0;
  out[0] = 0.0;
  for (int k = 1; k < n; k++) {
    double F = 0;
    for (int j = 1; j <= sub; j++) {
      double x1 = x[k-1] + (x[k] - x[k-1]) * (double)j / sub;
      F = step(&c, x1, &y, &e);
      if (!isfinite(F)) return 1;
    }
    out[k] = F;
  }
  return 0;
}
