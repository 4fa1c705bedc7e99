/* The co-simulation master loop of tuner/vehicle/cosim.py in C: a linear vehicle discretised exactly
 * over one communication step (first-order hold on the track inputs and on the damper forces) steps
 * nd damper FMUs already loaded and instantiated by fmpy, through their own fmi2SetReal,
 * fmi2SetRealInputDerivatives (may be NULL), fmi2DoStep and fmi2GetReal. The same arithmetic and
 * FMI calls as the Python loop there; depends on nothing but the FMI 2.0 calling convention.
 *
 * Step k (t_k = t0 + k h), for every damper i: stroke e = Ex x_k and rate ed = Ev x_k set at t_k
 * (co-simulation convention, input_interpolation = 0), the stroke acceleration
 * a = Ea x_k + accU_k + EBf F_k as the first derivative of stroke_velocity where the FMU takes it,
 * fmi2DoStep(t_k, h), force F_{k+1} read; then
 *     x_{k+1} = Phi x_k + forced_k + G1f F_k + G2f F_{k+1}
 * (G1f = G1 - G2 of the force columns, G2f = G2). Row-major matrices; X and F hold n + 1 rows, row 0
 * set by the caller. Stops after step k when max |x_{k+1}[abort_idx[j]]| > abort_limit (if n_abort
 * > 0). Returns 0, or the first FMI status worse than fmi2Warning (then *failed_step and
 * *failed_damper); *n_done: the last row of X written. */
#include <stddef.h>
#include <math.h>

typedef int (*SetReal)(void *, const unsigned int *, size_t, const double *);
typedef int (*SetDer)(void *, const unsigned int *, size_t, const int *, const double *);
typedef int (*DoStep)(void *, double, double, int);
typedef int (*GetReal)(void *, const unsigned int *, size_t, double *);

#define MAXD 16
#define MAXX 128

int vehicle_run(int n, int nx, int nd, const double *Phi, const double *forced, const double *G1f,
                const double *G2f, const double *Ex, const double *Ev, const double *Ea, const double *accU,
                const double *EBf, double t0, double h, void **set_real, void **set_der, void **do_step,
                void **get_real, void **comp, const unsigned int *vr, double *X, double *F,
                const int *abort_idx, int n_abort, double abort_limit, int *n_done, int *failed_step,
                int *failed_damper) {
    int k, i, j, st;
    double in[2], acc, xn[MAXX];
    const int order1 = 1;
    *n_done = 0;
    if (nd > MAXD || nx > MAXX) return 3;
    for (k = 0; k < n; k++) {
        const double *x = X + (size_t)k * nx, *Fk = F + (size_t)k * nd;
        double *Fn = F + (size_t)(k + 1) * nd, *xo = X + (size_t)(k + 1) * nx;
        double t = t0 + k * h;
        for (i = 0; i < nd; i++) {
            const double *ex = Ex + (size_t)i * nx, *ev = Ev + (size_t)i * nx, *ea = Ea + (size_t)i * nx;
            const unsigned int *v = vr + 3 * i;
            in[0] = 0.0; in[1] = 0.0; acc = accU[(size_t)k * nd + i];
            for (j = 0; j < nx; j++) { in[0] += ex[j] * x[j]; in[1] += ev[j] * x[j]; acc += ea[j] * x[j]; }
            for (j = 0; j < nd; j++) acc += EBf[i * nd + j] * Fk[j];
            st = ((SetReal)set_real[i])(comp[i], v, 2, in);
            if (st <= 1 && set_der[i]) st = ((SetDer)set_der[i])(comp[i], v + 1, 1, &order1, &acc);
            if (st <= 1) st = ((DoStep)do_step[i])(comp[i], t, h, 1);
            if (st <= 1) st = ((GetReal)get_real[i])(comp[i], v + 2, 1, Fn + i);
            if (st > 1) { *failed_step = k; *failed_damper = i; return st; }
        }
        for (j = 0; j < nx; j++) {
            const double *p = Phi + (size_t)j * nx, *g1 = G1f + (size_t)j * nd, *g2 = G2f + (size_t)j * nd;
            double s = forced[(size_t)k * nx + j];
            for (i = 0; i < nx; i++) s += p[i] * x[i];
            for (i = 0; i < nd; i++) s += g1[i] * Fk[i] + g2[i] * Fn[i];
            xn[j] = s;
        }
        for (j = 0; j < nx; j++) xo[j] = xn[j];
        *n_done = k + 1;
        if (n_abort > 0) {
            for (j = 0; j < n_abort; j++)
                if (!(fabs(xo[abort_idx[j]]) <= abort_limit)) return 0;
        }
    }
    return 0;
}
