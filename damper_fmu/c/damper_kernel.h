/* Damper models and their integrator in C: the kernel of the native FMUs and of the fast engine.
 *
 * It implements, operation for operation, the Python reference in damper_fmu/models.py,
 * effects.py and integrator.py (equations, sign conventions and algorithm are documented there);
 * tests/test_native.py holds the two equal to 1e-9 relative. SI units: stroke [m] positive in
 * extension, velocity [m/s], force [N] positive in tension, temperature [degC].
 * Depends on libc and libm only.
 */
#ifndef DAMPER_KERNEL_H
#define DAMPER_KERNEL_H

#include <stddef.h>

/* DK_<KIND>_<PARAMETER>: index of every parameter in a model's parameter vector, table sizes and
   blocks, parameter counts (generated from damper_fmu/parameters.py: python -m damper_fmu.c_header) */
#include "damper_index.h"

#define DK_LUMPED 0
#define DK_MAXWELL 1
#define DK_MAXWELL_TABLE 2
#define DK_TWOCHAMBER 3

#define DK_EXTRAPOLATE 0
#define DK_REPLAY 1

#define DK_NSTATE 7 /* largest model state (two-chamber) */

#define DK_MAXPTS 32 /* points of a table: its ordinates and the origin */
#if DK_LUMPED_FK_COUNT >= DK_MAXPTS || DK_LUMPED_FC_COUNT >= DK_MAXPTS || \
    DK_MAXWELL_TABLE_FC_COUNT >= DK_MAXPTS || DK_TWOCHAMBER_FC_COUNT >= DK_MAXPTS
#error "a table of damper_fmu/parameters.py has more points than DK_MAXPTS"
#endif

#define DK_OK 0
#define DK_ERROR 1

typedef struct {
    int n;                      /* number of points (origin included) */
    double xs[DK_MAXPTS], fs[DK_MAXPTS];
    double breaks[DK_MAXPTS];   /* interior breakpoints xs[1..n-2] */
    double slope[DK_MAXPTS], intercept[DK_MAXPTS], anchor[DK_MAXPTS];
    int nbreaks;
} DkTable;

typedef struct {
    int kind;
    double p[DK_NPAR_MAX];      /* parameter values, in MODEL_PARAMETERS order */
    /* lumped */
    double mC, mO, mP, kB, cB;
    DkTable fk, fc;
    double damping_scale;
    /* cached stage constants */
    int cached;
    double c_g, c_mP, c_mO, c_mC, c_d2, c_d4, c_ds;
    double c_ia[DK_MAXPTS], c_sa[DK_MAXPTS];
    /* Maxwell */
    double ks, c;
    /* two-chamber: mounts, chamber stiffnesses, area ratio, chamber lengths, air, gas spring;
       piston- and foot-valve tables; Newton tolerance [N] */
    double kM, cM, kR0, kC0, ar, LR, LC, air, fres, kgas, tc_tol;
    DkTable vp, vf;
    /* effects (lumped and two-chamber); inside: the two-chamber model's seal friction acts at the
       piston inside the mounts (its stage), not at the output, and its free play (tc_gap) is a
       dead band in its mount (gap 0) */
    double ff, v_eps, f0, gap, beta, heat_c, heat_g, t_ref, tau, delay, m_eq, tc_gap;
    /* form elements: pre-yield hysteresis (saturation force, displacement scale) and bypass groove
       (ratio, centre, width, edge length) */
    double fh, xh, bp_r, bp_c, bp_w, bp_e, bp_d, bp_v;
    int effects_active, inside;
} DkModel;

typedef struct {
    double x_eff, temperature, time;
    double x_seen, v_seen, z;   /* stroke [m] and velocity [m/s] seen at the end of the last step, hysteresis force [N] */
    int engaged;
    /* force history of the time delay: ring buffer of (time, force) pairs */
    double *hist;
    int hist_cap, hist_head, hist_len;
} DkEffectsState;

typedef struct {
    DkModel model;
    double max_step, tolerance;
    int input_mode;
    double y[DK_NSTATE];
    double x1, v1, force, time, h_next;
    int nsamples;
    double st[4], sv[4];        /* master's velocity samples, newest first */
    DkEffectsState e;
    double temperature_input;   /* measured oil temperature [degC] */
    int has_temperature;
    char msg[512];              /* last error message */
} DkSim;

/* Linkage of the kernel's entry points: external in the kernel library (damper_fmu/native.py); the
   FMU wrapper defines DK_API as static and includes damper_kernel.c, so that a binary or a program
   made of several FMUs' sources exposes the FMI functions only. */
#ifndef DK_API
#define DK_API
#endif

#ifndef DK_EMBEDDED
DK_API const char *dk_parameter_names(int kind);   /* comma-separated, for the consistency test */
DK_API int dk_parameter_count(int kind);
#endif

/* Build the model from parameter values (count must match); checks as check_values. */
DK_API int dk_model_init(DkModel *m, int kind, const double *p, int n, char *msg, size_t msglen);

DK_API void dk_sim_clear(DkSim *s);
DK_API void dk_sim_free(DkSim *s);
DK_API int dk_sim_setup(DkSim *s, int kind, const double *p, int n, double max_step, double tolerance,
                 int input_mode);
DK_API int dk_sim_initialize(DkSim *s, double x1, double v1, double t0);
/* accel: stroke acceleration from the master, or NULL (estimate it) */
DK_API int dk_sim_step(DkSim *s, double h, double x1, double v1, const double *accel);
/* copy the state (deep copy of the history) */
DK_API int dk_sim_copy(DkSim *dst, const DkSim *src);
/* internal element outputs: 8 values (lumped), 5 (two-chamber) or 1 (Maxwell) */
DK_API int dk_diagnostics(const DkSim *s, double *out);

#ifndef DK_EMBEDDED
/* Whole sampled stroke; temperature may be NULL. out[0] is the initial force. */
DK_API int dk_simulate(int kind, const double *p, int np, double max_step, double tolerance, int input_mode,
                int n, const double *t, const double *x, const double *v, const double *temp,
                double *out, char *msg, int msglen);

#endif

#endif
