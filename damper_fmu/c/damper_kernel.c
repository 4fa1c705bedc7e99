/* Damper models and their integrator in C (see damper_kernel.h). Mirrors, operation for
 * operation, damper_fmu/models.py, effects.py and integrator.py: read those for the physics. */
#include "damper_kernel.h"
#include "damper_params.h"

/* the parameter specs (damper_params.h, generated per build) and the committed index names
   (damper_index.h) come from the same damper_fmu/parameters.py: refuse a stale header */
#if DK_PARAMS_LUMPED_N != DK_LUMPED_N || DK_PARAMS_MAXWELL_N != DK_MAXWELL_N || \
    DK_PARAMS_MAXWELL_TABLE_N != DK_MAXWELL_TABLE_N || DK_PARAMS_TWOCHAMBER_N != DK_TWOCHAMBER_N
#error "damper_index.h is out of date with damper_fmu/parameters.py: python -m damper_fmu.c_header"
#endif

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_NEWTON 12
/* what double precision resolves of a sum of terms, relative to the sum of their magnitudes: where every
   iterative solve ends (models.py: _RESOLUTION) */
#define RESOLUTION (4.0 * DBL_EPSILON)
#define MIN_STEP 1e-12
/* relative slack of the sub-step division (integrator.py: STEP_RTOL): a communication step that
   differs from a whole number of max_step by float jitter ((k+1)h - kh) is taken as that number of
   max_step, and no step ends in a sliver sub-step */
#define STEP_RTOL 1e-6
#define MAX_SPLITS 8

/* Internal step attempts in one communication step, beyond which it fails (integrator.py:
   MAX_ATTEMPTS): every loop of the kernel is bounded, whatever the arithmetic gives. */
#define MAX_ATTEMPTS 100000
/* Communication steps longer than this many max_step fail (the sub-step count is an int). */
#define MAX_STEP_RATIO 1e8

static double GAMMA_, C21_;

/* Finite test on the bit pattern (exponent not all ones). -ffast-math and -ffinite-math-only let the
   compiler fold isfinite()/isnan()/isinf() to constants, which turned a NaN into a hang or a NaN
   force returned as fmi2OK; an importer's build flags must not do that. */
static int dk_finite(double x) {
    unsigned long long u;
    memcpy(&u, &x, sizeof u);
    return (u & 0x7ff0000000000000ULL) != 0x7ff0000000000000ULL;
}

static void constants(void) {
    if (GAMMA_ == 0.0) {
        GAMMA_ = 1.0 - 1.0 / sqrt(2.0);
        C21_ = (1.0 - GAMMA_) / GAMMA_;
    }
}

static const DkParamSpec *specs(int kind, int *n) {
    switch (kind) {
    case DK_LUMPED: *n = DK_PARAMS_LUMPED_N; return DK_PARAMS_LUMPED;
    case DK_MAXWELL: *n = DK_PARAMS_MAXWELL_N; return DK_PARAMS_MAXWELL;
    case DK_MAXWELL_TABLE: *n = DK_PARAMS_MAXWELL_TABLE_N; return DK_PARAMS_MAXWELL_TABLE;
    case DK_TWOCHAMBER: *n = DK_PARAMS_TWOCHAMBER_N; return DK_PARAMS_TWOCHAMBER;
    default: *n = 0; return NULL;
    }
}

#ifndef DK_EMBEDDED /* the FMU wrapper does not use these */
DK_API int dk_parameter_count(int kind) {
    int n;
    specs(kind, &n);
    return n;
}

DK_API const char *dk_parameter_names(int kind) {
    static char buf[4096];
    int n, i;
    const DkParamSpec *sp = specs(kind, &n);
    buf[0] = 0;
    for (i = 0; i < n; i++) {
        if (i) strcat(buf, ",");
        strcat(buf, sp[i].name);
    }
    return buf;
}
#endif

/* ---- piecewise-linear tables (tables.py) ---------------------------------------------------- */

static int bisect_right(const double *a, int n, double x) {
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < a[mid]) hi = mid; else lo = mid + 1;
    }
    return lo;
}

static int table_init(DkTable *t, const double *xs_in, const double *fs_in, int n, const char *name,
                      char *msg, size_t msglen) {
    int i, k = -1, j;
    for (i = 0; i < n; i++) {
        if (!dk_finite(xs_in[i]) || !dk_finite(fs_in[i])) {
            snprintf(msg, msglen, "%s table: abscissa %d or its ordinate is not finite", name, i + 1);
            return DK_ERROR;
        }
        if (i && !(xs_in[i] > xs_in[i - 1])) {
            snprintf(msg, msglen, "%s abscissae must be strictly increasing (abscissa %d = %g after %g)",
                     name, i + 1, xs_in[i], xs_in[i - 1]);
            return DK_ERROR;
        }
    }
    if (!(xs_in[0] < 0.0 && 0.0 < xs_in[n - 1])) {
        snprintf(msg, msglen, "%s abscissae must have negative and positive values (F(0) = 0 is implied)", name);
        return DK_ERROR;
    }
    for (i = 0; i < n; i++)
        if (xs_in[i] > 0.0) { k = i; break; }
    for (i = 0, j = 0; i <= n; i++) {
        if (i == k) { t->xs[i] = 0.0; t->fs[i] = 0.0; }
        else { t->xs[i] = xs_in[j]; t->fs[i] = fs_in[j]; j++; }
    }
    t->n = n + 1;
    for (i = 0; i + 1 < t->n; i++) {
        double s = (t->fs[i + 1] - t->fs[i]) / (t->xs[i + 1] - t->xs[i]);
        if (s < 0.0) {
            snprintf(msg, msglen, "%s table is not monotone: the force falls between abscissae %g and %g "
                     "(a passive element needs non-decreasing ordinates)", name, t->xs[i], t->xs[i + 1]);
            return DK_ERROR;
        }
        t->slope[i] = s;
        t->intercept[i] = t->fs[i] - s * t->xs[i];
    }
    t->nbreaks = t->n - 2;
    for (i = 0; i < t->nbreaks; i++) t->breaks[i] = t->xs[i + 1];
    t->anchor[k] = 0.0;
    for (i = k + 1; i < t->n; i++)
        t->anchor[i] = t->anchor[i - 1] + 0.5 * (t->fs[i] + t->fs[i - 1]) * (t->xs[i] - t->xs[i - 1]);
    for (i = k - 1; i >= 0; i--)
        t->anchor[i] = t->anchor[i + 1] - 0.5 * (t->fs[i] + t->fs[i + 1]) * (t->xs[i + 1] - t->xs[i]);
    return DK_OK;
}

static int segment(const DkTable *t, double x) { return bisect_right(t->breaks, t->nbreaks, x); }

static double table_eval(const DkTable *t, double x) {
    int i = segment(t, x);
    return t->intercept[i] + t->slope[i] * x;
}

/* from the node of x's piece nearer the origin (tables.py: PwlTable.primitive) */
static double table_primitive(const DkTable *t, double x) {
    int i = segment(t, x), j = t->xs[i + 1] <= 0.0 ? i + 1 : i;
    double x0 = t->xs[j];
    return t->anchor[j] + t->intercept[i] * (x - x0) + 0.5 * t->slope[i] * (x * x - x0 * x0);
}

/* ---- parameters and models ------------------------------------------------------------------- */

/* the effect parameters: the block e of parameters.EFFECT_PARAMETERS */
static void effects_init(DkModel *m, const double *e) {
    m->ff = e[DK_EFFECT_FRICTION_FORCE]; m->v_eps = e[DK_EFFECT_FRICTION_VELOCITY];
    m->f0 = e[DK_EFFECT_PRELOAD_FORCE]; m->gap = e[DK_EFFECT_FREE_PLAY]; m->beta = e[DK_EFFECT_THERMAL_BETA];
    m->heat_c = e[DK_EFFECT_THERMAL_CAPACITY]; m->heat_g = e[DK_EFFECT_THERMAL_CONDUCTANCE];
    m->t_ref = e[DK_EFFECT_THERMAL_REFERENCE]; m->tau = e[DK_EFFECT_VALVE_TAU]; m->delay = e[DK_EFFECT_TIME_DELAY];
    m->m_eq = e[DK_EFFECT_INERTIA_MASS];
    m->fh = e[DK_EFFECT_HYSTERESIS_FORCE]; m->xh = e[DK_EFFECT_HYSTERESIS_DISPLACEMENT];
    m->bp_r = e[DK_EFFECT_BYPASS_RATIO]; m->bp_c = e[DK_EFFECT_BYPASS_CENTER];
    m->bp_w = e[DK_EFFECT_BYPASS_WIDTH]; m->bp_e = e[DK_EFFECT_BYPASS_EDGE];
    m->bp_d = e[DK_EFFECT_BYPASS_DIRECTION]; m->bp_v = e[DK_EFFECT_BYPASS_VELOCITY];
    m->effects_active = m->ff != 0.0 || m->f0 != 0.0 || m->gap != 0.0 || m->beta != 0.0 ||
                        m->tau != 0.0 || m->delay != 0.0 || m->m_eq != 0.0 || m->fh != 0.0 || m->bp_r != 0.0;
}

#define TC_CHECK_SHARE 4e-3  /* models.py: CHECK_SHARE */

DK_API int dk_model_init(DkModel *m, int kind, const double *p, int n, char *msg, size_t msglen) {
    int np, i;
    const DkParamSpec *sp = specs(kind, &np);
    memset(m, 0, sizeof(*m));
    if (!sp) { snprintf(msg, msglen, "unknown model kind %d", kind); return DK_ERROR; }
    if (n != np) { snprintf(msg, msglen, "expected %d parameters, got %d", np, n); return DK_ERROR; }
    for (i = 0; i < np; i++) {
        double v = p[i];
        if (!dk_finite(v)) {
            snprintf(msg, msglen, "parameter %s = %g is not finite", sp[i].name, v);
            return DK_ERROR;
        }
        if (sp[i].check == DK_CHECK_RANGE && !(sp[i].low <= v && v <= sp[i].high)) {
            snprintf(msg, msglen, "%sparameter %s = %g %s outside [%g, %g]", sp[i].effect ? "effect " : "",
                     sp[i].name, v, sp[i].unit, sp[i].low, sp[i].high);
            return DK_ERROR;
        }
        if (sp[i].check == DK_CHECK_POSITIVE && !(v > 0.0)) {
            snprintf(msg, msglen, "parameter %s = %g %s must be positive", sp[i].name, v, sp[i].unit);
            return DK_ERROR;
        }
        if (sp[i].check == DK_CHECK_NONNEGATIVE && !(v >= 0.0)) {
            snprintf(msg, msglen, "parameter %s = %g %s must not be negative", sp[i].name, v, sp[i].unit);
            return DK_ERROR;
        }
        m->p[i] = v;
    }
    m->kind = kind;
    m->damping_scale = 1.0;
    if (kind == DK_LUMPED) {
        m->mC = p[DK_LUMPED_M_C]; m->mO = p[DK_LUMPED_M_O]; m->mP = p[DK_LUMPED_M_P];
        m->kB = p[DK_LUMPED_K_B]; m->cB = p[DK_LUMPED_C_B];
        if (table_init(&m->fk, p + DK_LUMPED_FK_X01, p + DK_LUMPED_FK_01, DK_LUMPED_FK_COUNT, "Fk", msg, msglen))
            return DK_ERROR;
        if (table_init(&m->fc, p + DK_LUMPED_FC_V01, p + DK_LUMPED_FC_01, DK_LUMPED_FC_COUNT, "Fc", msg, msglen))
            return DK_ERROR;
        effects_init(m, p + DK_LUMPED_EFFECTS);
    } else if (kind == DK_MAXWELL) {
        m->ks = p[DK_MAXWELL_K_S]; m->c = p[DK_MAXWELL_C];
    } else if (kind == DK_TWOCHAMBER) {
        double xs[DK_TWOCHAMBER_FC_COUNT + 1], fs[DK_TWOCHAMBER_FC_COUNT + 1], cchk = p[DK_TWOCHAMBER_CHECK_DAMPING], r;
        int k, np_ = 0;
        m->kM = p[DK_TWOCHAMBER_K_M]; m->cM = p[DK_TWOCHAMBER_C_M]; m->kR0 = p[DK_TWOCHAMBER_K_R];
        m->kC0 = p[DK_TWOCHAMBER_K_C]; m->ar = p[DK_TWOCHAMBER_AREA_RATIO]; m->LR = p[DK_TWOCHAMBER_L_R];
        m->LC = p[DK_TWOCHAMBER_L_C]; m->air = p[DK_TWOCHAMBER_AIR]; m->fres = p[DK_TWOCHAMBER_F_RES];
        m->kgas = p[DK_TWOCHAMBER_K_GAS];
        if (table_init(&m->fc, p + DK_TWOCHAMBER_FC_V01, p + DK_TWOCHAMBER_FC_01, DK_TWOCHAMBER_FC_COUNT, "Fc", msg,
                       msglen))
            return DK_ERROR;
        r = 1.0 - m->ar;
        if (cchk == 0.0) {  /* TC_CHECK_SHARE of the table's mean slope to its last rate (models.py: CHECK_SHARE) */
            double peak = 0.0, span = 0.0;
            for (k = 0; k < m->fc.n; k++) {
                if (fabs(m->fc.fs[k]) > peak) peak = fabs(m->fc.fs[k]);
                if (fabs(m->fc.xs[k]) > span) span = fabs(m->fc.xs[k]);
            }
            cchk = TC_CHECK_SHARE * peak / span;
        }
        /* piston valve: the check (slope cchk) below zero, the table's rebound half above */
        xs[0] = -1.0; fs[0] = -cchk; np_ = 1;
        for (k = 0; k < m->fc.n; k++)
            if (m->fc.xs[k] > 0.0) { xs[np_] = m->fc.xs[k]; fs[np_] = m->fc.fs[k]; np_++; }
        if (table_init(&m->vp, xs, fs, np_, "piston valve", msg, msglen)) return DK_ERROR;
        /* foot valve: the intake check below zero, Ff(u) = -Fc(-u / r) / r above */
        xs[0] = -1.0; fs[0] = -cchk; np_ = 1;
        for (k = m->fc.n - 1; k >= 0; k--)
            if (m->fc.xs[k] < 0.0) { xs[np_] = -r * m->fc.xs[k]; fs[np_] = -m->fc.fs[k] / r; np_++; }
        if (table_init(&m->vf, xs, fs, np_, "foot valve", msg, msglen)) return DK_ERROR;
        effects_init(m, p + DK_TWOCHAMBER_EFFECTS);
        m->inside = 1;
        m->tc_gap = m->gap;  /* the free play is the mount's dead band (models.py: TwoChamberModel.mount) */
        m->gap = 0.0;
        m->effects_active = m->ff != 0.0 || m->f0 != 0.0 || m->beta != 0.0 || m->tau != 0.0 || m->delay != 0.0 ||
                            m->m_eq != 0.0 || m->fh != 0.0 || m->bp_r != 0.0;
    } else {
        m->ks = p[DK_MAXWELL_TABLE_K_S];
        if (table_init(&m->fc, p + DK_MAXWELL_TABLE_FC_V01, p + DK_MAXWELL_TABLE_FC_01, DK_MAXWELL_TABLE_FC_COUNT, "Fc",
                       msg, msglen))
            return DK_ERROR;
    }
    return DK_OK;
}

static double force_scale(const DkModel *m) {
    int i;
    double s = 0.0;
    if (m->kind == DK_MAXWELL) return m->c * 0.1;
    for (i = 0; i < m->fc.n; i++)
        if (fabs(m->fc.fs[i]) > s) s = fabs(m->fc.fs[i]);
    return s;
}

static double model_force(const DkModel *m, const double *y, double x1, double v1) {
    if (m->kind == DK_LUMPED) return m->kB * (x1 - y[0]) + m->cB * (v1 - y[3]);
    if (m->kind == DK_TWOCHAMBER) {
        double f = y[1] - y[2] + m->kgas * (x1 - y[3]);
        if (m->ff != 0.0) f += m->ff * tanh(y[6] / m->v_eps);
        return f;
    }
    return m->ks * (x1 - y[0]);
}

static double error_norm(const DkModel *m, const double *ya, const double *yb) {
    if (m->kind == DK_LUMPED) {
        double a = fabs(m->kB * (yb[0] - ya[0]) + m->cB * (yb[3] - ya[3]));
        double b = fabs(m->kB * (yb[2] - ya[2]) + m->cB * (yb[5] - ya[5]));
        return a > b ? a : b;
    }
    if (m->kind == DK_TWOCHAMBER) {
        double a = fabs(yb[1] - ya[1]), b = fabs(yb[2] - ya[2]);
        return a > b ? a : b;
    }
    return fabs(m->ks * (yb[0] - ya[0]));
}

static void stage_constants(DkModel *m, double g) {
    int i;
    double ds = m->damping_scale, kBg = m->kB * g;
    m->c_g = g;
    m->c_mP = m->mP / g; m->c_mO = m->mO / g; m->c_mC = m->mC / g;
    m->c_d2 = m->c_mP + kBg + m->cB;
    m->c_d4 = m->c_mC + kBg + m->cB;
    for (i = 0; i + 1 < m->fc.n; i++) {
        m->c_ia[i] = ds != 1.0 ? ds * m->fc.intercept[i] : m->fc.intercept[i];
        m->c_sa[i] = ds != 1.0 ? ds * m->fc.slope[i] : m->fc.slope[i];
    }
    m->c_ds = ds;
    m->cached = 1;
}

static double lumped_potential(const DkModel *m, const double *v, const double *yb, double g, double x1,
                               double v1) {
    double x2b = yb[0], x3b = yb[1], x4b = yb[2], v2b = yb[3], v3b = yb[4], v4b = yb[5];
    double v2 = v[0], v3 = v[1], v4 = v[2];
    double kB = m->kB, cB = m->cB;
    double e = x3b - x4b + g * (v3 - v4);
    double a = x1 - x2b - g * v2, b = x4b + g * v4, c = v1 - v2;
    return (0.5 * (m->mP * ((v2 - v2b) * (v2 - v2b)) + m->mO * ((v3 - v3b) * (v3 - v3b)) +
                   m->mC * ((v4 - v4b) * (v4 - v4b))) / g
            + 0.5 * kB / g * (a * a + b * b)
            + 0.5 * cB * (c * c + v4 * v4)
            + m->damping_scale * table_primitive(&m->fc, v2 - v3) + table_primitive(&m->fk, e) / g);
}

static int lumped_stage_damped(DkModel *m, const double *yb, double g, double x1, double v1, double *out,
                               char *msg, size_t msglen) {
    double x2b = yb[0], x3b = yb[1], x4b = yb[2], v2b = yb[3], v3b = yb[4], v4b = yb[5];
    double mP, mO, mC, d2, d4, kB = m->kB, cB = m->cB, dxb, v[3], phi;
    const double *ia, *sa, *ka = m->fk.intercept, *ks = m->fk.slope;
    int it;
    if (!m->cached || m->c_g != g || m->c_ds != m->damping_scale) stage_constants(m, g);
    mP = m->c_mP; mO = m->c_mO; mC = m->c_mC; d2 = m->c_d2; d4 = m->c_d4; ia = m->c_ia; sa = m->c_sa;
    dxb = x3b - x4b;
    v[0] = v2b; v[1] = v3b; v[2] = v4b;
    phi = lumped_potential(m, v, yb, g, x1, v1);
    for (it = 0; it < 200; it++) {
        double v2 = v[0], v3 = v[1], v4 = v[2];
        double u = v2 - v3, e = dxb + g * (v3 - v4);
        int ic = segment(&m->fc, u), ik = segment(&m->fk, e);
        double sc = sa[ic], skg = ks[ik] * g;
        double fcu = ia[ic] + sc * u, fke = ka[ik] + ks[ik] * e;
        double r0 = mP * (v2 - v2b) - kB * (x1 - x2b - g * v2) - cB * (v1 - v2) + fcu;
        double r1 = mO * (v3 - v3b) - fcu + fke;
        double r2 = mC * (v4 - v4b) - fke + kB * (x4b + g * v4) + cB * v4;
        double a11 = d2 + sc, a22 = mO + sc + skg, a33 = d4 + skg;
        double w1 = -sc / a11, w2, y1, y2, d3, d2_, d1, scale, size, alpha, trial[3], phi_t;
        a22 -= sc * sc / a11;
        w2 = -skg / a22;
        a33 -= skg * skg / a22;
        y1 = -r0 / a11;
        y2 = (-r1 + sc * y1) / a22;
        d3 = (-r2 + skg * y2) / a33;
        d2_ = y2 - w2 * d3;
        d1 = y1 - w1 * d2_;
        scale = fabs(d1) + fabs(d2_) + fabs(d3);
        size = (mP * (fabs(v2) + fabs(v2b)) + mO * (fabs(v3) + fabs(v3b)) + mC * (fabs(v4) + fabs(v4b))
                + kB * (fabs(x1) + fabs(x2b) + fabs(x4b) + g * (fabs(v2) + fabs(v4)))
                + cB * (fabs(v1) + fabs(v2) + fabs(v4))
                + 2.0 * (fabs(fcu) + fabs(fke)) + sc * (fabs(v2) + fabs(v3)) + skg * (fabs(v3) + fabs(v4))
                + ks[ik] * fabs(dxb));
        /* the step within rounding of the velocities, or the residuals within rounding of their terms */
        if (scale <= RESOLUTION * (fabs(v2) + fabs(v3) + fabs(v4)) ||
            fabs(r0) + fabs(r1) + fabs(r2) <= RESOLUTION * size) {
            out[0] = x2b + g * v2; out[1] = x3b + g * v3; out[2] = x4b + g * v4;
            out[3] = v2; out[4] = v3; out[5] = v4;
            return DK_OK;
        }
        alpha = 1.0;
        for (;;) {
            trial[0] = v2 + alpha * d1; trial[1] = v3 + alpha * d2_; trial[2] = v4 + alpha * d3;
            phi_t = lumped_potential(m, trial, yb, g, x1, v1);
            if (phi_t <= phi || alpha < 1e-12) break;
            alpha *= 0.5;
        }
        v[0] = trial[0]; v[1] = trial[1]; v[2] = trial[2];
        phi = phi_t;
    }
    snprintf(msg, msglen, "lumped model stage: damped Newton did not converge (non-monotonic table?)");
    return DK_ERROR;
}

static int lumped_stage(DkModel *m, const double *yb, double g, double x1, double v1, double *out,
                        char *msg, size_t msglen) {
    double x2b = yb[0], x3b = yb[1], x4b = yb[2], v2b = yb[3], v3b = yb[4], v4b = yb[5];
    double mP, mO, mC, d2, d4, kB = m->kB, cB = m->cB, dxb, r2, r3, r4;
    const double *ia, *sa, *bc = m->fc.breaks, *bk = m->fk.breaks, *ka = m->fk.intercept, *ks = m->fk.slope;
    int nbc = m->fc.nbreaks, nbk = m->fk.nbreaks, ic, ik, it;
    if (!m->cached || m->c_g != g || m->c_ds != m->damping_scale) stage_constants(m, g);
    mP = m->c_mP; mO = m->c_mO; mC = m->c_mC; d2 = m->c_d2; d4 = m->c_d4; ia = m->c_ia; sa = m->c_sa;
    dxb = x3b - x4b;
    r2 = mP * v2b + kB * (x1 - x2b) + cB * v1;
    r3 = mO * v3b;
    r4 = mC * v4b - kB * x4b;
    ic = bisect_right(bc, nbc, v2b - v3b);
    ik = bisect_right(bk, nbk, dxb + g * (v3b - v4b));
    for (it = 0; it < MAX_NEWTON; it++) {
        double sc = sa[ic], ac = ia[ic];
        double skg = ks[ik] * g;
        double akx = ka[ik] + ks[ik] * dxb;
        double a11 = d2 + sc;
        double w1 = -sc / a11;
        double y1 = (r2 - ac) / a11;
        double a22 = mO + sc + skg + sc * w1;
        double w2 = -skg / a22;
        double y2 = (r3 + ac - akx + sc * y1) / a22;
        double a33 = d4 + skg + skg * w2;
        double v2, v3, v4;
        int jc, jk;
        if (a11 <= 0.0 || a22 <= 0.0 || a33 <= 0.0) {
            snprintf(msg, msglen, "stage Jacobian not positive definite (non-monotonic table?)");
            return DK_ERROR;
        }
        v4 = (r4 + akx + skg * y2) / a33;
        v3 = y2 - w2 * v4;
        v2 = y1 - w1 * v3;
        jc = bisect_right(bc, nbc, v2 - v3);
        jk = bisect_right(bk, nbk, dxb + g * (v3 - v4));
        if (jc == ic && jk == ik) {
            out[0] = x2b + g * v2; out[1] = x3b + g * v3; out[2] = x4b + g * v4;
            out[3] = v2; out[4] = v3; out[5] = v4;
            return DK_OK;
        }
        ic = jc; ik = jk;
    }
    return lumped_stage_damped(m, yb, g, x1, v1, out, msg, msglen);
}

static double maxwell_table_residual(const DkModel *m, double z, double kg, double rhs) {
    return table_eval(&m->fc, z) + kg * z - rhs;
}

static int maxwell_table_stage(DkModel *m, const double *yb, double g, double x1, double *out,
                               char *msg, size_t msglen) {
    const DkTable *fc = &m->fc;
    double ks = m->ks, rhs = ks * (x1 - yb[0]), kg = ks * g, lo = -1.0, hi = 1.0;
    int i = segment(fc, rhs / (fc->slope[(fc->n - 1) / 2] + kg)), it;
    for (it = 0; it < MAX_NEWTON; it++) {
        double den = fc->slope[i] + kg, vd;
        int j;
        if (den <= 0.0) {
            snprintf(msg, msglen, "Maxwell table stage: non-monotonic dashpot table");
            return DK_ERROR;
        }
        vd = (rhs - fc->intercept[i]) / den;
        j = bisect_right(fc->breaks, fc->nbreaks, vd);
        if (j == i) { out[0] = yb[0] + g * vd; return DK_OK; }
        i = j;
    }
    for (it = 0; it < 1100 && maxwell_table_residual(m, lo, kg, rhs) > 0.0; it++) lo *= 2.0;
    for (it = 0; it < 1100 && maxwell_table_residual(m, hi, kg, rhs) < 0.0; it++) hi *= 2.0;
    if (!dk_finite(lo) || !dk_finite(hi) || !dk_finite(rhs)) {
        snprintf(msg, msglen, "Maxwell table stage: no bracket of the dashpot velocity (non-finite state)");
        return DK_ERROR;
    }
    for (it = 0; it < 200; it++) {
        double mid = 0.5 * (lo + hi);
        if (maxwell_table_residual(m, mid, kg, rhs) > 0.0) hi = mid; else lo = mid;
        if (hi - lo <= RESOLUTION * fmax(fabs(lo), fabs(hi))) break;
    }
    out[0] = yb[0] + g * (0.5 * (lo + hi));
    return DK_OK;
}


/* ---- two-chamber model (models.py, TwoChamberModel) ------------------------------------------- */

#define TC_AIR_EXPONENT 1.714
#define TC_CLIP 0.05
#define TC_TOL 1e-10
#define TC_MAX_NEWTON 60
#define TC_PLAIN 12
#define TC_MAX_HALVINGS 40
#define TC_MAX_NESTED 200
#define TC_PLAY_SMOOTHING 1e-5  /* m, models.py: PLAY_SMOOTHING */
#define TC_DISENGAGED 1e-6  /* models.py: _TC_DISENGAGED */

/* n x n (n <= 5) Gaussian elimination with partial pivoting; DK_ERROR when singular */
static int solve_n(double a[5][5], const double *b, double *x, int n) {
    double m[5][6];
    int i, j, k, p;
    for (i = 0; i < n; i++) { for (j = 0; j < n; j++) m[i][j] = a[i][j]; m[i][n] = b[i]; }
    for (k = 0; k < n; k++) {
        p = k;
        for (i = k + 1; i < n; i++)
            if (fabs(m[i][k]) > fabs(m[p][k])) p = i;
        if (fabs(m[p][k]) < 1e-300) return DK_ERROR;
        if (p != k)
            for (j = 0; j <= n; j++) { double t = m[k][j]; m[k][j] = m[p][j]; m[p][j] = t; }
        for (i = k + 1; i < n; i++) {
            double f = m[i][k] / m[k][k];
            for (j = k; j <= n; j++) m[i][j] -= f * m[k][j];
        }
    }
    for (i = n - 1; i >= 0; i--) {
        double s_ = m[i][n];
        for (j = i + 1; j < n; j++) s_ -= m[i][j] * x[j];
        x[i] = s_ / m[i][i];
    }
    return DK_OK;
}

/* The full stage system J d = r of tc_residual (unknowns w, up, uf, fR, gC), solved by its pattern: rows 3 and 4
   give gC from uf and fR from w and uf (unit pivots: dr3/dgC = 1, dr4/dfR = 1), the other three rows then form
   a 3 x 3 system in (w, up, uf) for solve_n. A third of the work of solve_n on the 5 x 5 (models.py:
   _solve_stage); DK_ERROR when singular. */
static int tc_solve_stage(double J[5][5], const double *r, double *d) {
    double A[5][5], b[3], x[3], a3, b3, a4, c4, b4;
    if (fabs(J[3][4]) < 1e-300 || fabs(J[4][3]) < 1e-300) return DK_ERROR;
    a3 = r[3] / J[3][4]; b3 = -J[3][2] / J[3][4];                /* d_gC = a3 + b3 d_uf */
    a4 = (r[4] - J[4][4] * a3) / J[4][3];                        /* d_fR = a4 + c4 d_w + b4 d_uf */
    c4 = -J[4][0] / J[4][3]; b4 = -J[4][4] * b3 / J[4][3];
    A[0][0] = J[0][0] + J[0][3] * c4; A[0][1] = J[0][1]; A[0][2] = J[0][3] * b4;
    b[0] = r[0] - J[0][3] * a4;
    A[1][0] = J[1][0]; A[1][1] = J[1][1]; A[1][2] = J[1][2] + J[1][4] * b3;
    b[1] = r[1] - J[1][4] * a3;
    A[2][0] = J[2][3] * c4; A[2][1] = J[2][1]; A[2][2] = J[2][3] * b4 + J[2][4] * b3;
    b[2] = r[2] - J[2][3] * a4 - J[2][4] * a3;
    if (solve_n(A, b, x, 3)) return DK_ERROR;
    d[0] = x[0]; d[1] = x[1]; d[2] = x[2];
    d[4] = a3 + b3 * x[2];
    d[3] = a4 + c4 * x[0] + b4 * x[2];
    return DK_OK;
}

/* chamber stiffnesses and derivatives: k[0..5] = kR, dkR/dy, dkR/dfR, kC, dkC/dy, dkC/dgC */
static void tc_stiffness(const DkModel *m, double y, double fR, double gC, double *k) {
    double s = 1.0 - y / m->LR, kR, kRy, kC, kCy, kRf = 0.0, kCg = 0.0;
    int side;
    if (s > TC_CLIP) { kR = m->kR0 / s; kRy = kR / (m->LR * s); }
    else { kR = m->kR0 / TC_CLIP; kRy = 0.0; }
    s = 1.0 + y / m->LC;
    if (s > TC_CLIP) { kC = m->kC0 / s; kCy = -kC / (m->LC * s); }
    else { kC = m->kC0 / TC_CLIP; kCy = 0.0; }
    if (m->air > 0.0) {
        for (side = 0; side < 2; side++) {
            double scale = side == 0 ? m->ar * m->fres : m->fres;
            double e = (side == 0 ? fR : gC) / scale + 1.0 - TC_CLIP, root = sqrt(e * e + TC_CLIP * TC_CLIP);
            double ratio = TC_CLIP + 0.5 * (e + root), q, dq, d;
            q = pow(ratio, -TC_AIR_EXPONENT);
            dq = -TC_AIR_EXPONENT * q / ratio * (0.5 * (1.0 + e / root)) / scale;
            d = 1.0 + m->air * q;
            if (side == 0) { kR = kR / d; kRy = kRy / d; kRf = -kR * m->air * dq / d; }
            else { kC = kC / d; kCy = kCy / d; kCg = -kC * m->air * dq / d; }
        }
    }
    k[0] = kR; k[1] = kRy; k[2] = kRf; k[3] = kC; k[4] = kCy; k[5] = kCg;
}

static double sigmoid(double z) {
    double ez;
    if (z >= 0.0) return 1.0 / (1.0 + exp(-z));
    ez = exp(z);
    return ez / (1.0 + ez);
}

/* mount force at elongation e, rate edot, with dF/de (*fe) and dF/dedot (*fd): a dead band of width
   tc_gap in the spring, the damper acting where engaged (models.py: TwoChamberModel.mount) */
static double tc_mount(const DkModel *m, double e, double edot, double *fe, double *fd) {
    double h = 0.5 * m->tc_gap, w = TC_PLAY_SMOOTHING, z1 = (e - h) / w, z2 = (-e - h) / w, d, s1, s2, chi, dchi;
    if (m->tc_gap == 0.0) { *fe = m->kM; *fd = m->cM; return m->kM * e + m->cM * edot; }
    d = w * (fmax(z1, 0.0) + log1p(exp(-fabs(z1))) - fmax(z2, 0.0) - log1p(exp(-fabs(z2))));
    s1 = sigmoid(z1); s2 = sigmoid(z2); chi = s1 + s2; dchi = (s1 * (1.0 - s1) - s2 * (1.0 - s2)) / w;
    *fe = m->kM * chi + m->cM * dchi * edot;
    *fd = m->cM * chi;
    return m->kM * d + m->cM * chi * edot;
}

/* the stage residuals r [N] at q = (w, up, uf, fR, gC), their Jacobian J (unless NULL) and the size sz [N] of each
   residual: the sum of the magnitudes of its terms, with a term's change over the rounding of the positions and
   velocities it takes (models.py: TwoChamberModel._residual) */
static void tc_residual(const DkModel *m, const double *q, const double *yb, double g, double x1, double v1,
                        double *r, double J[5][5], double *sz) {
    double w = q[0], up = q[1], uf = q[2], fR = q[3], gC = q[4], a = m->ar, y = yb[0] + g * w, k[6];
    double uR, uC, sp, sf, ap, af, ds = m->damping_scale, fr = 0.0, dfr = 0.0, fe, fd, fm;
    int ip = segment(&m->vp, up), jf = segment(&m->vf, uf);
    tc_stiffness(m, y, fR, gC, k);
    uR = w - up; uC = -w + a * up - uf;
    sp = ds * m->vp.slope[ip]; sf = ds * m->vf.slope[jf];
    ap = ds * m->vp.intercept[ip]; af = ds * m->vf.intercept[jf];
    if (m->ff != 0.0) {
        double th = tanh(w / m->v_eps);
        fr = m->ff * th; dfr = m->ff * (1.0 - th * th) / m->v_eps;
    }
    fm = tc_mount(m, x1 - y, v1 - w, &fe, &fd);
    r[0] = fR - yb[1] - g * k[0] * uR;
    r[1] = gC - yb[2] - g * k[3] * uC;
    r[2] = fR - a * gC - (ap + sp * up);
    r[3] = gC - (af + sf * uf);
    r[4] = fR - gC + fr - fm;
    sz[0] = fabs(fR) + fabs(yb[1]) + g * k[0] * (fabs(w) + fabs(up));
    sz[1] = fabs(gC) + fabs(yb[2]) + g * k[3] * (fabs(w) + a * fabs(up) + fabs(uf));
    sz[2] = fabs(fR) + a * fabs(gC) + fabs(ap) + fabs(sp * up);
    sz[3] = fabs(gC) + fabs(af) + fabs(sf * uf);
    sz[4] = fabs(fR) + fabs(gC) + fabs(fr) + dfr * fabs(w) + fabs(fm) + fabs(fe) * (fabs(x1) + fabs(y))
            + fabs(fd) * (fabs(v1) + fabs(w));
    if (J) {
        J[0][0] = -g * (k[0] + g * k[1] * uR); J[0][1] = g * k[0]; J[0][2] = 0.0;
        J[0][3] = 1.0 - g * k[2] * uR; J[0][4] = 0.0;
        J[1][0] = -g * (-k[3] + g * k[4] * uC); J[1][1] = -g * k[3] * a; J[1][2] = g * k[3];
        J[1][3] = 0.0; J[1][4] = 1.0 - g * k[5] * uC;
        J[2][0] = 0.0; J[2][1] = -sp; J[2][2] = 0.0; J[2][3] = 1.0; J[2][4] = -a;
        J[3][0] = 0.0; J[3][1] = 0.0; J[3][2] = -sf; J[3][3] = 0.0; J[3][4] = 1.0;
        J[4][0] = g * fe + fd + dfr; J[4][1] = 0.0; J[4][2] = 0.0; J[4][3] = 1.0; J[4][4] = -1.0;
    }
}

static double abs_sum(const double *r, int n) {
    double s = fabs(r[0]);
    int i;
    for (i = 1; i < n; i++) s += fabs(r[i]);
    return s;
}

/* tolerance [N] on the sum of the first n |residuals|: TC_TOL of the force scale, or what double precision
   resolves of them where that is more (models.py: TwoChamberModel._tolerance) */
static double tc_tolerance(const DkModel *m, const double *sz, int n) {
    double floor_ = RESOLUTION * abs_sum(sz, n);
    return m->tc_tol > floor_ ? m->tc_tol : floor_;
}

/* Newton's method on the stage residuals for the unknowns q[held..4] (q[0..held-1] stay as given),
   on as many residuals as unknowns: full steps first, then a backtracking line search on the sum of
   those |residuals| (models.py: TwoChamberModel._newton). On return r, J are at q, *rn is the
   residual sum and *tol its tolerance at q; DK_ERROR when a Jacobian could not be solved. */
static int tc_newton(DkModel *m, double *q, int held, const double *yb, double g, double x1, double v1,
                     double *r, double J[5][5], double *rn, double *tol) {
    double A[5][5], d[5], qt[5], rt[5], sz[5], rnt = 0.0;
    int n = 5 - held, it, i, j, h;
    tc_residual(m, q, yb, g, x1, v1, r, J, sz);
    *rn = abs_sum(r, n);
    *tol = tc_tolerance(m, sz, n);
    for (it = 0; it < TC_MAX_NEWTON; it++) {
        int accepted = 0;
        double lam = 1.0;
        if (*rn <= *tol) break;
        if (held == 0) {
            if (tc_solve_stage(J, r, d)) return DK_ERROR;
        } else {
            for (i = 0; i < n; i++) for (j = 0; j < n; j++) A[i][j] = J[i][j + held];
            if (solve_n(A, r, d, n)) return DK_ERROR;
        }
        if (it < TC_PLAIN) {
            for (i = 0; i < n; i++) q[i + held] = q[i + held] - d[i];
            tc_residual(m, q, yb, g, x1, v1, r, J, sz);
            *rn = abs_sum(r, n);
            *tol = tc_tolerance(m, sz, n);
            continue;
        }
        for (h = 0; h < TC_MAX_HALVINGS; h++) {
            for (i = 0; i < held; i++) qt[i] = q[i];
            for (i = 0; i < n; i++) qt[i + held] = q[i + held] - lam * d[i];
            tc_residual(m, qt, yb, g, x1, v1, rt, NULL, sz);
            rnt = abs_sum(rt, n);
            if (rnt < *rn) { accepted = 1; break; }
            lam *= 0.5;
        }
        if (!accepted) break;
        for (i = 0; i < 5; i++) q[i] = qt[i];
        *rn = rnt;
        tc_residual(m, q, yb, g, x1, v1, r, J, sz);
        *tol = tc_tolerance(m, sz, n);
    }
    return DK_OK;
}

/* the chamber and valve equations (residuals 0-3) solved for p4 = (up, uf, fR, gC) at the piston
   velocity w; *dfw = d(fR - gC)/dw, *tol the tolerance of the sum of |r0..r3| it returns (models.py:
   _valves_given_w) */
static double tc_valves_given_w(DkModel *m, double w, double *p4, const double *yb, double g, double x1,
                                double v1, double *dfw, double *tol) {
    double q[5], r[5], J[5][5], A[5][5], d[5], rhs[5], rn;
    int i, j;
    q[0] = w;
    for (i = 0; i < 4; i++) q[i + 1] = p4[i];
    tc_newton(m, q, 1, yb, g, x1, v1, r, J, &rn, tol); /* a singular Jacobian ends the iteration: rn says how far */
    for (i = 0; i < 4; i++) {
        for (j = 0; j < 4; j++) A[i][j] = J[i][j + 1];
        rhs[i] = -J[i][0];
    }
    *dfw = solve_n(A, rhs, d, 4) ? 0.0 : d[2] - d[3];
    for (i = 0; i < 4; i++) p4[i] = q[i + 1];
    return rn;
}

/* fallback of tc_stage: safeguarded Newton (bisection once bracketed) on the mount balance, which
   increases with w when the other equations are solved for each w (models.py: _stage_nested); rn0, tol0: the
   joint iteration's residual sum and tolerance, for the message when this fails too */
static int tc_stage_nested(DkModel *m, const double *yb, double g, double x1, double v1, double w0, double rn0,
                           double tol0, double *q, char *msg, size_t msglen) {
    double p4[4], w = w0, lo = 0.0, hi = 0.0, r[5], qq[5], sz[5];
    int it, i, have_lo = 0, have_hi = 0; /* bracket ends found (no infinities: see dk_finite) */
    p4[0] = yb[4]; p4[1] = yb[5]; p4[2] = yb[1]; p4[3] = yb[2];
    for (it = 0; it < TC_MAX_NESTED; it++) {
        double dfw, rn4, tol4, fr_slope = 0.0, slope, wn;
        rn4 = tc_valves_given_w(m, w, p4, yb, g, x1, v1, &dfw, &tol4);
        if (!(rn4 <= tol4)) break;
        qq[0] = w;
        for (i = 0; i < 4; i++) qq[i + 1] = p4[i];
        tc_residual(m, qq, yb, g, x1, v1, r, NULL, sz);
        if (fabs(r[4]) <= tc_tolerance(m, sz, 5)) {
            for (i = 0; i < 5; i++) q[i] = qq[i];
            return DK_OK;
        }
        if (m->ff != 0.0) {
            double th = tanh(w / m->v_eps);
            fr_slope = m->ff * (1.0 - th * th) / m->v_eps;
        }
        {
            double fe, fd;
            tc_mount(m, x1 - (yb[0] + g * w), v1 - w, &fe, &fd);
            slope = dfw + fr_slope + g * fe + fd;
        }
        if (r[4] > 0.0) { hi = w; have_hi = 1; } else { lo = w; have_lo = 1; }
        wn = w - r[4] / slope;
        if (!((!have_lo || lo < wn) && (!have_hi || wn < hi))) {
            if (!have_lo || !have_hi) wn = w - 2.0 * r[4] / slope;
            else wn = 0.5 * (lo + hi);
        }
        if (have_lo && have_hi && hi - lo <= RESOLUTION * fmax(fabs(lo), fabs(hi))) break; /* a few ulps of w wide */
        if (!dk_finite(wn)) break;
        w = wn;
    }
    snprintf(msg, msglen, "two-chamber stage: Newton stalled at a residual of %.3g N and the nested solve did not "
             "converge either (tolerance %.3g N)", rn0, tol0);
    return DK_ERROR;
}

static int tc_stage(DkModel *m, const double *yb, double g, double x1, double v1, double *out, char *msg,
                    size_t msglen) {
    double fb = yb[1] - yb[2] + (m->ff != 0.0 ? m->ff * tanh(yb[6] / m->v_eps) : 0.0), q[5], w0, r[5], J[5][5], rn, tol;
    if (m->tc_tol == 0.0) m->tc_tol = TC_TOL * force_scale(m);
    if (m->tc_gap == 0.0) q[0] = (m->cM * v1 - fb + m->kM * (x1 - yb[0])) / (m->cM + m->kM * g);
    else { /* the mount with its dead band linearised at the last piston velocity (models.py: stage) */
        double fe, fd, wp = yb[6], fm = tc_mount(m, x1 - (yb[0] + g * wp), v1 - wp, &fe, &fd), den = g * fe + fd;
        q[0] = den > TC_DISENGAGED * (m->cM + m->kM * g) ? wp + (fm - fb) / den : wp;
    }
    q[1] = yb[4]; q[2] = yb[5]; q[3] = yb[1]; q[4] = yb[2];
    w0 = q[0];
    if (tc_newton(m, q, 0, yb, g, x1, v1, r, J, &rn, &tol)) {
        snprintf(msg, msglen, "two-chamber stage: singular Jacobian");
        return DK_ERROR;
    }
    if (!(rn <= tol) && tc_stage_nested(m, yb, g, x1, v1, w0, rn, tol, q, msg, msglen)) return DK_ERROR;
    out[0] = yb[0] + g * q[0]; out[1] = q[3]; out[2] = q[4]; out[3] = yb[3]; out[4] = q[1]; out[5] = q[2];
    out[6] = q[0];
    return DK_OK;
}

static int stage(DkModel *m, const double *yb, double g, double x1, double v1, double *out, char *msg,
                 size_t msglen) {
    if (m->kind == DK_LUMPED) return lumped_stage(m, yb, g, x1, v1, out, msg, msglen);
    if (m->kind == DK_TWOCHAMBER) return tc_stage(m, yb, g, x1, v1, out, msg, msglen);
    if (m->kind == DK_MAXWELL) {
        double a = g * m->ks / m->c;
        out[0] = (yb[0] + a * x1) / (1.0 + a);
        return DK_OK;
    }
    return maxwell_table_stage(m, yb, g, x1, out, msg, msglen);
}

static int n_state(const DkModel *m) { return m->kind == DK_LUMPED ? 6 : m->kind == DK_TWOCHAMBER ? 7 : 1; }

static double valve_gain(const DkModel *m, double u) {
    const DkTable *fc = &m->fc;
    int k0 = segment(fc, 0.0), i, lo = u >= 0.0 ? k0 : 0, hi = u >= 0.0 ? fc->n - 1 : k0;
    double mx = fc->slope[lo < hi ? lo : 0];
    for (i = lo; i < hi; i++)
        if (fc->slope[i] > mx) mx = fc->slope[i];
    return m->damping_scale * (mx - fc->slope[segment(fc, u)]);
}

/* ---- effects (effects.py) --------------------------------------------------------------------- */

static void play(const DkModel *m, double *x_eff, int *engaged, double *x1, double *v1) {
    double half;
    if (m->gap == 0.0) return;
    half = 0.5 * m->gap;
    if (*x1 - *x_eff >= half) { *x_eff = *x1 - half; *engaged = 1; }
    else if (*x1 - *x_eff <= -half) { *x_eff = *x1 + half; *engaged = 1; }
    else *engaged = 0;
    *x1 = *x_eff;
    if (!*engaged) *v1 = 0.0;
}

static int hist_push(DkEffectsState *e, double t, double f) {
    if (e->hist_len == e->hist_cap) {
        int cap = e->hist_cap ? 2 * e->hist_cap : 64, i;
        double *h = (double *)malloc(2 * (size_t)cap * sizeof(double));
        if (!h) return DK_ERROR;
        for (i = 0; i < e->hist_len; i++) {
            int k = (e->hist_head + i) % e->hist_cap;
            h[2 * i] = e->hist[2 * k]; h[2 * i + 1] = e->hist[2 * k + 1];
        }
        free(e->hist);
        e->hist = h; e->hist_cap = cap; e->hist_head = 0;
    }
    {
        int k = (e->hist_head + e->hist_len) % e->hist_cap;
        e->hist[2 * k] = t; e->hist[2 * k + 1] = f;
        e->hist_len++;
    }
    return DK_OK;
}

static const double *hist_at(const DkEffectsState *e, int i) {
    return e->hist + 2 * ((e->hist_head + i) % e->hist_cap);
}

static void effects_initialize(DkSim *s, double x1, double v1, double force) {
    DkEffectsState *e = &s->e;
    e->x_eff = x1; e->engaged = 1; e->temperature = s->model.t_ref; e->time = 0.0;
    e->x_seen = x1; e->v_seen = v1; e->z = 0.0;
    e->hist_len = 0; e->hist_head = 0;
    hist_push(e, 0.0, force);
}

/* factor on the damping characteristic for the next step: thermal drift and bypass groove, the
   latter at the stroke seen at the end of the last step (effects.py: damping_scale) */
static double damping_scale(const DkSim *s) {
    const DkModel *m = &s->model;
    double scale = m->beta != 0.0 ? exp(-m->beta * (s->e.temperature - m->t_ref)) : 1.0;
    double v = s->e.v_seen;
    if (m->bp_r != 0.0 && !((m->bp_d > 0.5 && v <= 0.0) || (m->bp_d < -0.5 && v >= 0.0))) {
        double u = s->e.x_seen - m->bp_c, half = 0.5 * m->bp_w;
        double q = m->bp_v != 0.0 ? v / m->bp_v : 0.0, r = m->bp_r / (1.0 + q * q);
        scale *= 1.0 - r * 0.5 * (tanh((u + half) / m->bp_e) - tanh((u - half) / m->bp_e));
    }
    return scale;
}

/* the measured force at the end of a step (effects.py: output); x_eff, v_eff: the stroke and
   velocity the damper sees at the end of the step */
static int effects_output(DkSim *s, double f_model, double h, double x_eff, double v_eff, double a1, double vg,
                          double *out) {
    const DkModel *m = &s->model;
    DkEffectsState *e = &s->e;
    double f = (e->engaged || m->gap == 0.0) ? f_model : 0.0, target, t0, f0, t1, f1;
    if (m->fh != 0.0) {  /* Dahl element: exact for a monotone increment of the stroke seen */
        double dx = x_eff - e->x_seen;
        if (dx != 0.0) {
            double sat = dx > 0.0 ? m->fh : -m->fh;
            e->z = sat + (e->z - sat) * exp(-fabs(dx) / m->xh);
        }
        if (e->engaged || m->gap == 0.0) f += e->z;
    }
    e->x_seen = x_eff; e->v_seen = v_eff;
    if (m->ff != 0.0 && !m->inside) f += m->ff * tanh(v_eff / m->v_eps);
    if (m->tau != 0.0 && (e->engaged || m->gap == 0.0)) f += m->tau * vg * a1;
    if (m->m_eq != 0.0) f += m->m_eq * a1;
    f += m->f0;
    if (m->beta != 0.0) {
        if (s->has_temperature) e->temperature = s->temperature_input;
        else { /* the thermal balance solved exactly over the step at its power (effects.py: output) */
            double power = f_model * v_eff, decay = -expm1(-h * m->heat_g / m->heat_c);
            e->temperature += (power / m->heat_g - (e->temperature - m->t_ref)) * decay;
        }
    }
    e->time += h;
    if (m->delay == 0.0) { *out = f; return DK_OK; }
    if (hist_push(e, e->time, f)) return DK_ERROR;
    target = e->time - m->delay;
    while (e->hist_len > 2 && hist_at(e, 1)[0] <= target) {
        e->hist_head = (e->hist_head + 1) % e->hist_cap;
        e->hist_len--;
    }
    t0 = hist_at(e, 0)[0]; f0 = hist_at(e, 0)[1];
    if (e->hist_len > 1) { t1 = hist_at(e, 1)[0]; f1 = hist_at(e, 1)[1]; } else { t1 = t0; f1 = f0; }
    if (target <= t0 || t1 == t0) *out = f0;
    else *out = f0 + (f1 - f0) * (target - t0) / (t1 - t0);
    return DK_OK;
}

/* ---- integrator (integrator.py) -------------------------------------------------------------- */

DK_API void dk_sim_clear(DkSim *s) { memset(s, 0, sizeof(*s)); }

DK_API void dk_sim_free(DkSim *s) {
    free(s->e.hist);
    s->e.hist = NULL;
    s->e.hist_cap = s->e.hist_len = s->e.hist_head = 0;
}

DK_API int dk_sim_setup(DkSim *s, int kind, const double *p, int n, double max_step, double tolerance,
                 int input_mode) {
    constants();
    if (!(max_step > 0.0 && dk_finite(max_step))) {
        snprintf(s->msg, sizeof s->msg, "max_step must be a positive number of seconds, got %g", max_step);
        return DK_ERROR;
    }
    if (input_mode != DK_EXTRAPOLATE && input_mode != DK_REPLAY) {
        snprintf(s->msg, sizeof s->msg, "input_mode must be 0 (extrapolate) or 1 (replay), got %d", input_mode);
        return DK_ERROR;
    }
    if (!(tolerance >= 0.0 && dk_finite(tolerance))) {
        snprintf(s->msg, sizeof s->msg, "tolerance must be a non-negative number, got %g", tolerance);
        return DK_ERROR;
    }
    if (dk_model_init(&s->model, kind, p, n, s->msg, sizeof s->msg)) return DK_ERROR;
    s->max_step = max_step;
    s->tolerance = tolerance;
    s->input_mode = input_mode;
    return DK_OK;
}

DK_API int dk_sim_initialize(DkSim *s, double x1, double v1, double t0) {
    DkModel *m = &s->model;
    if (!(dk_finite(x1) && dk_finite(v1))) {
        snprintf(s->msg, sizeof s->msg, "non-finite input: stroke=%g, stroke_velocity=%g", x1, v1);
        return DK_ERROR;
    }
    memset(s->y, 0, sizeof s->y);
    if (m->kind == DK_LUMPED) { s->y[0] = x1; s->y[3] = v1; s->y[4] = v1; }
    else if (m->kind == DK_TWOCHAMBER) { s->y[0] = x1; s->y[3] = x1; s->y[6] = v1; }
    else s->y[0] = x1;
    s->x1 = x1; s->v1 = v1; s->time = t0; s->h_next = s->max_step; s->nsamples = 0;
    s->force = model_force(m, s->y, x1, v1);
    if (m->effects_active) {
        effects_initialize(s, x1, v1, s->force);
        s->force += m->f0 + (m->ff != 0.0 && !m->inside ? m->ff * tanh(v1 / m->v_eps) : 0.0);
    }
    return DK_OK;
}

static void velocity_extrapolation(const DkSim *s, double *a, double *j, double *sn) {
    const double *t = s->st, *v = s->sv;
    double d01, d12, d012;
    *a = *j = *sn = 0.0;
    if (s->nsamples < 3) return;
    d01 = (v[0] - v[1]) / (t[0] - t[1]);
    d12 = (v[1] - v[2]) / (t[1] - t[2]);
    d012 = (d01 - d12) / (t[0] - t[2]);
    if (s->nsamples == 4) {
        double d23 = (v[2] - v[3]) / (t[2] - t[3]);
        double j1 = d01 - d12, j2 = d12 - d23;
        double mx = fabs(j1) > fabs(j2) ? fabs(j1) : fabs(j2);
        if (j1 * j2 > 0.0 && fabs(j1 - j2) <= 0.5 * mx) {
            double d0123 = (d012 - (d12 - d23) / (t[1] - t[3])) / (t[0] - t[3]);
            *a = d01 + d012 * (t[0] - t[1]) + d0123 * (t[0] - t[1]) * (t[0] - t[2]);
            *j = 2.0 * d012 + 2.0 * d0123 * ((t[0] - t[1]) + (t[0] - t[2]));
            *sn = d0123;
            return;
        }
    }
    if (d01 * d12 <= 0.0) return;
    {
        double mx = fabs(d01) > fabs(d12) ? fabs(d01) : fabs(d12);
        if (fabs(d01 - d12) <= 0.5 * mx) {
            *a = d01 + d012 * (t[0] - t[1]);
            *j = 2.0 * d012;
            return;
        }
    }
    *a = fabs(d01) <= fabs(d12) ? d01 : d12;
}

typedef struct {
    double x0, v0, c2, c3;
} Traj;

/* One SDIRK2 step of size H from tau; y, play state in/out; xs, vs: what the damper sees at the end */
static int sdirk(DkSim *s, const Traj *tr, const double *y, double *yout, double *x_eff, int *engaged,
                 double tau, double H, double *xs, double *vs) {
    DkModel *m = &s->model;
    int ns = n_state(m), i;
    double g = GAMMA_ * H, y1[DK_NSTATE], yb[DK_NSTATE];
    double t1 = tau + g, t2 = tau + H;
    double xa = tr->x0 + t1 * (tr->v0 + t1 * (tr->c2 + t1 * tr->c3));
    double va = tr->v0 + t1 * (2.0 * tr->c2 + 3.0 * tr->c3 * t1);
    double xb, vb;
    int fx = m->effects_active;
    if (fx) play(m, x_eff, engaged, &xa, &va);
    if (stage(m, y, g, xa, va, y1, s->msg, sizeof s->msg)) return DK_ERROR;
    xb = tr->x0 + t2 * (tr->v0 + t2 * (tr->c2 + t2 * tr->c3));
    vb = tr->v0 + t2 * (2.0 * tr->c2 + 3.0 * tr->c3 * t2);
    if (fx) play(m, x_eff, engaged, &xb, &vb);
    for (i = 0; i < ns; i++) yb[i] = y[i] + C21_ * (y1[i] - y[i]);
    if (stage(m, yb, g, xb, vb, yout, s->msg, sizeof s->msg)) return DK_ERROR;
    *xs = xb; *vs = vb;
    return DK_OK;
}

/* a fixed sub-step; one whose stage solve fails is taken as two halves, recursively (integrator.py: split) */
static int sdirk_split(DkSim *s, const Traj *tr, const double *y, double *yout, double *x_eff, int *engaged,
                       double tau, double H, double *xs, double *vs, int depth) {
    double xe = *x_eff, ym[DK_NSTATE];
    int en = *engaged;
    if (sdirk(s, tr, y, yout, &xe, &en, tau, H, xs, vs) == DK_OK) {
        *x_eff = xe; *engaged = en;
        return DK_OK;
    }
    if (depth >= MAX_SPLITS) return DK_ERROR;
    xe = *x_eff; en = *engaged;
    if (sdirk_split(s, tr, y, ym, &xe, &en, tau, 0.5 * H, xs, vs, depth + 1)) return DK_ERROR;
    if (sdirk_split(s, tr, ym, yout, &xe, &en, tau + 0.5 * H, 0.5 * H, xs, vs, depth + 1)) return DK_ERROR;
    *x_eff = xe; *engaged = en;
    return DK_OK;
}

DK_API int dk_sim_step(DkSim *s, double h, double x1, double v1, const double *accel) {
    DkModel *m = &s->model;
    int ns = n_state(m), i, fx = m->effects_active;
    double xh, vh, d, y[DK_NSTATE], xs, vs, x_eff = s->e.x_eff, va0, f;
    int engaged = s->e.engaged;
    Traj tr;
    if (!(dk_finite(x1) && dk_finite(v1))) {
        snprintf(s->msg, sizeof s->msg, "non-finite input: stroke=%g, stroke_velocity=%g", x1, v1);
        return DK_ERROR;
    }
    if (!(h > 0.0 && dk_finite(h))) {
        snprintf(s->msg, sizeof s->msg, "step size must be a positive finite number, got %g", h);
        return DK_ERROR;
    }
    {   /* a step within STEP_RTOL of a whole number of max_step is taken as exactly that (integrator.py) */
        double n = ceil(h / (s->max_step * (1.0 + STEP_RTOL))), hn;
        if (n < 1.0) n = 1.0;
        hn = n * s->max_step;
        if (fabs(h - hn) <= STEP_RTOL * hn) h = hn;
    }
    if (h / s->max_step > MAX_STEP_RATIO) {
        snprintf(s->msg, sizeof s->msg, "communication step %g s is more than %g internal steps of %g s", h,
                 MAX_STEP_RATIO, s->max_step);
        return DK_ERROR;
    }
    if (s->input_mode == DK_EXTRAPOLATE) {
        double a, j, sn;
        for (i = 3; i > 0; i--) { s->st[i] = s->st[i - 1]; s->sv[i] = s->sv[i - 1]; }
        s->st[0] = s->time; s->sv[0] = v1;
        if (s->nsamples < 4) s->nsamples++;
        if (accel && dk_finite(*accel)) { a = *accel; j = 0.0; sn = 0.0; }
        else velocity_extrapolation(s, &a, &j, &sn);
        xh = x1 + h * (v1 + h * (0.5 * a + h * (j / 6.0 + 0.25 * sn * h)));
        vh = v1 + h * (a + h * (0.5 * j + sn * h));
    } else {
        xh = x1; vh = v1;
    }
    tr.x0 = s->x1; tr.v0 = s->input_mode == DK_EXTRAPOLATE ? v1 : s->v1;
    d = (xh - tr.x0) / h;
    tr.c2 = (3.0 * d - 2.0 * tr.v0 - vh) / h;
    tr.c3 = (tr.v0 + vh - 2.0 * d) / (h * h);
    if (fx) m->damping_scale = damping_scale(s);
    for (i = 0; i < ns; i++) y[i] = s->y[i];
    xs = xh; vs = vh;
    if (s->tolerance == 0.0) {
        int n = (int)ceil(h / (s->max_step * (1.0 + STEP_RTOL))), k;
        double H;
        if (n < 1) n = 1;
        H = h / n;
        for (k = 0; k < n; k++) {
            double yn[DK_NSTATE];
            if (sdirk_split(s, &tr, y, yn, &x_eff, &engaged, k * H, H, &xs, &vs, 0)) return DK_ERROR;
            memcpy(y, yn, sizeof y);
        }
    } else {
        double tol = s->tolerance * force_scale(m), tau = 0.0;
        double H = s->h_next < s->max_step ? s->h_next : s->max_step;
        int attempt;
        for (attempt = 0;; attempt++) {
            double proposed = H, yf[DK_NSTATE], ym[DK_NSTATE], y2[DK_NSTATE], xe1 = x_eff, xe2, x2, v2, err, fac, dummy_x, dummy_v;
            int en1 = engaged, en2, last = tau + H * (1.0 + STEP_RTOL) >= h;
            double xf = x_eff;
            int enf = engaged;
            if (last) H = h - tau;
            int failed;
            if (attempt >= MAX_ATTEMPTS) {
                snprintf(s->msg, sizeof s->msg, "more than %d internal step attempts in one communication step "
                         "at t = %.9g s (last internal step %.3g s)", MAX_ATTEMPTS, s->time + tau, H);
                return DK_ERROR;
            }
            xe2 = xe1; en2 = en1; x2 = v2 = 0.0;
            /* a failed stage solve (message in s->msg) or a non-finite error: retry with a 5x smaller step */
            failed = sdirk(s, &tr, y, yf, &xf, &enf, tau, H, &dummy_x, &dummy_v) ||
                     sdirk(s, &tr, y, ym, &xe1, &en1, tau, 0.5 * H, &dummy_x, &dummy_v) ||
                     (xe2 = xe1, en2 = en1, sdirk(s, &tr, ym, y2, &xe2, &en2, tau + 0.5 * H, 0.5 * H, &x2, &v2));
            err = failed ? 0.0 : error_norm(m, yf, y2);
            if (!failed && !dk_finite(err)) {
                failed = 1;
                snprintf(s->msg, sizeof s->msg, "non-finite local error estimate");
            }
            if (failed) fac = 0.2;
            else if (err == 0.0) fac = 4.0;
            else {
                fac = 0.9 * pow(tol / err, 1.0 / 3.0);
                if (fac < 0.2) fac = 0.2;
                if (fac > 4.0) fac = 4.0;
            }
            if (!failed && err <= tol) {
                memcpy(y, y2, sizeof y);
                x_eff = xe2; engaged = en2; xs = x2; vs = v2;
                if (last) {
                    double hn = H * fac > proposed ? H * fac : proposed;
                    s->h_next = s->max_step < hn ? s->max_step : hn;
                    break;
                }
                tau += H;
                H = s->max_step < H * fac ? s->max_step : H * fac;
            } else {
                H *= fac;
                if (!(H >= MIN_STEP)) {
                    char why[300];
                    if (failed) snprintf(why, sizeof why, "last: %.290s", s->msg);
                    else snprintf(why, sizeof why, "error %.3g N, tolerance %.3g N", err, tol);
                    snprintf(s->msg, sizeof s->msg, "internal step fell below %g s at t = %.9g s (%s)", MIN_STEP,
                             s->time + tau, why);
                    return DK_ERROR;
                }
            }
        }
    }
    for (i = 0; i < ns; i++) s->y[i] = y[i];
    s->time += h;
    va0 = tr.v0;
    s->x1 = xh; s->v1 = vh;
    if (fx) {
        s->e.x_eff = x_eff; s->e.engaged = engaged;
        if (effects_output(s, model_force(m, y, xs, vs), h, xs, vs, (vh - va0) / h,
                           m->tau != 0.0 ? valve_gain(m, vs) : 0.0, &f)) {
            snprintf(s->msg, sizeof s->msg, "out of memory for the time-delay history");
            return DK_ERROR;
        }
    } else {
        f = model_force(m, y, xs, vs);
    }
    if (!dk_finite(f)) {
        snprintf(s->msg, sizeof s->msg, "damper force became non-finite");
        return DK_ERROR;
    }
    s->force = f;
    return DK_OK;
}

DK_API int dk_sim_copy(DkSim *dst, const DkSim *src) {
    double *hist = dst->e.hist;
    int cap = dst->e.hist_cap, i;
    *dst = *src;
    dst->e.hist = hist;
    dst->e.hist_cap = cap;
    if (src->e.hist_len > cap) {
        free(hist);
        dst->e.hist = (double *)malloc(2 * (size_t)src->e.hist_len * sizeof(double));
        dst->e.hist_cap = src->e.hist_len;
        if (!dst->e.hist) { dst->e.hist_cap = dst->e.hist_len = 0; return DK_ERROR; }
    }
    dst->e.hist_head = 0;
    for (i = 0; i < src->e.hist_len; i++) {
        const double *q = hist_at(&src->e, i);
        dst->e.hist[2 * i] = q[0]; dst->e.hist[2 * i + 1] = q[1];
    }
    return DK_OK;
}

DK_API int dk_diagnostics(const DkSim *s, double *out) {
    const DkModel *m = &s->model;
    const double *y = s->y;
    if (m->kind == DK_LUMPED) {
        double u = y[3] - y[4], e = y[1] - y[2];
        out[0] = s->x1 - y[0];
        out[1] = s->v1 - y[3];
        out[2] = u;
        out[3] = m->damping_scale * table_eval(&m->fc, u);
        out[4] = e;
        out[5] = table_eval(&m->fk, e);
        out[6] = y[2];
        out[7] = m->kB * y[2] + m->cB * y[5];
        return 8;
    }
    if (m->kind == DK_TWOCHAMBER) {
        out[0] = s->x1 - y[0]; out[1] = y[1]; out[2] = y[2]; out[3] = y[4]; out[4] = y[5];
        return 5;
    }
    out[0] = s->x1 - y[0];
    return 1;
}

#ifndef DK_EMBEDDED
DK_API int dk_simulate(int kind, const double *p, int np, double max_step, double tolerance, int input_mode,
                int n, const double *t, const double *x, const double *v, const double *temp,
                double *out, char *msg, int msglen) {
    DkSim s;
    int k, status = DK_OK;
    dk_sim_clear(&s);
    if (n < 2) { snprintf(msg, msglen, "need at least 2 samples"); return DK_ERROR; }
    if (dk_sim_setup(&s, kind, p, np, max_step, tolerance, input_mode)) goto fail;
    if (temp) { s.has_temperature = 1; s.temperature_input = temp[0]; }
    if (dk_sim_initialize(&s, x[0], v[0], t[0])) goto fail;
    out[0] = s.force;
    for (k = 1; k < n; k++) {
        int j = input_mode == DK_REPLAY ? k : k - 1;
        if (temp) s.temperature_input = temp[j];
        if (dk_sim_step(&s, t[k] - t[k - 1], x[j], v[j], NULL)) {
            char tmp[400];
            snprintf(tmp, sizeof tmp, "%.399s", s.msg);
            snprintf(s.msg, sizeof s.msg, "step %d (t = %.9g s): %s", k, t[k - 1], tmp);
            goto fail;
        }
        out[k] = s.force;
    }
    dk_sim_free(&s);
    return DK_OK;
fail:
    snprintf(msg, msglen, "%s", s.msg);
    dk_sim_free(&s);
    status = DK_ERROR;
    return status;
}
#endif
