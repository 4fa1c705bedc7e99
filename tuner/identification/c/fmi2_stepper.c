/* A co-simulation master's stepping loop in C, for any FMI 2.0 co-simulation FMU already loaded
 * and instantiated by fmpy (tuner/identification/runner.py passes the FMU's own fmi2SetReal, fmi2DoStep and
 * fmi2GetReal). It makes exactly the calls the Python loop makes, sample by sample, without the
 * interpreter's overhead per call. Depends on nothing but the FMI 2.0 calling convention. */
#include <stddef.h>

typedef int (*SetReal)(void *, const unsigned int *, size_t, const double *);
typedef int (*DoStep)(void *, double, double, int);
typedef int (*GetReal)(void *, const unsigned int *, size_t, double *);

/* Steps samples 1..n-1: inputs of sample k - shift (shift 0: end-of-step values, 1: start-of-step),
 * then fmi2DoStep(t[k-1], t[k] - t[k-1]), then the outputs into out[k * nout ...]. Inputs are
 * x, v and, if temp is not NULL, temp (nin = 2 or 3). Returns the first status worse than
 * fmi2Warning (and the sample in *failed), else 0. */
int fmi2_run(void *set_real, void *do_step, void *get_real, void *comp, int n, const double *t,
             const double *x, const double *v, const double *temp, const unsigned int *vr_in, int nin,
             const unsigned int *vr_out, int nout, int shift, double *out, int *failed) {
    SetReal sr = (SetReal)set_real;
    DoStep ds = (DoStep)do_step;
    GetReal gr = (GetReal)get_real;
    double in[3];
    int k, st;
    for (k = 1; k < n; k++) {
        int j = k - shift;
        in[0] = x[j];
        in[1] = v[j];
        if (nin > 2) in[2] = temp[j];
        st = sr(comp, vr_in, (size_t)nin, in);
        if (st <= 1) st = ds(comp, t[k - 1], t[k] - t[k - 1], 1);
        if (st <= 1) st = gr(comp, vr_out, (size_t)nout, out + (size_t)k * (size_t)nout);
        if (st > 1) {
            *failed = k;
            return st;
        }
    }
    return 0;
}
