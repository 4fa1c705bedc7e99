/* The co-simulation master loop of tuner/vehicle/nonlinear_cosim.py in C: the nonlinear car of
 * campaign/vehicle_nonlinear.py (linear bodies and suspension, wheel-rail contact of campaign/contact.py:
 * conical rolling radii, Shen-Hedrick-Elkins saturating creep, flange dead band) steps nd damper FMUs
 * already loaded and instantiated by fmpy, through their own fmi2SetReal, fmi2SetRealInputDerivatives
 * (may be NULL), fmi2DoStep and fmi2GetReal. The same arithmetic and FMI calls as the Python loop there.
 *
 * Mechanical state x (nx = 2 ndof values: displacements then rates, SI units). Its derivative with the
 * damper forces F: dx = Am x + Af F, plus on each wheelset w (lateral state index wi[w], yaw index
 * nb + wi[w], nb bodies) the contact's lateral force times inv_m[w] on row ndof + wi[w] and its yaw
 * moment times inv_i[w] on row ndof + nb + wi[w]. c = {conicity, r0, b0, f11, f22, mu N, flange clearance,
 * flange stiffness, speed}.
 *
 * Step k (t_k = k h), for every damper i: stroke E x_k[:ndof], its rate E x_k[ndof:] and its acceleration
 * E dx_k[ndof:] (the first derivative of stroke_velocity where the FMU takes it), fmi2DoStep(t_k, h),
 * force F_{k+1} read; then m classical Runge-Kutta steps of x over [t_k, t_k + h] with F linear from F_k to
 * F_{k+1}. Row-major matrices; X and F hold n + 1 rows, row 0 set by the caller. Returns 0, 3 when the
 * sizes exceed the buffers, or the first FMI status worse than fmi2Warning (then *failed_step and
 * *failed_damper). */
#include <stddef.h>
#include <math.h>

typedef int (*SetReal)(void *, const unsigned int *, size_t, const double *);
typedef int (*SetDer)(void *, const unsigned int *, size_t, const int *, const double *);
typedef int (*DoStep)(void *, double, double, int);
typedef int (*GetReal)(void *, const unsigned int *, size_t, double *);

#define MAXD 16
#define MAXX 128

typedef struct {
    int nx, nd, nw, ndof, nb;
    const double *Am, *Af, *inv_m, *inv_i, *c;
    const int *wi;
} Car;

static void contact(const Car *car, const double *x, double *dx) {
    const double *c = car->c;
    const double lam = c[0], r0 = c[1], b0 = c[2], f11 = c[3], f22 = c[4], mun = c[5], gap = c[6], kf = c[7];
    const double V = c[8];
    int w;
    for (w = 0; w < car->nw; w++) {
        int iy = car->wi[w], ip = car->nb + iy;
        double y = x[iy], psi = x[ip], yd = x[car->ndof + iy], om = x[car->ndof + ip];
        double xi_x = -((b0 / V) * om + (lam * y) / r0);
        double xi_y = yd * (1.0 / V) - psi;
        double fx = -f11 * xi_x, fy = -f22 * xi_y;
        double beta = sqrt(fx * fx + fy * fy) * (1.0 / mun);
        double s = beta < 3.0 ? 1.0 - beta * (1.0 / 3.0 - beta / 27.0) : 1.0 / beta;
        double fl = -kf * (fmax(y - gap, 0.0) + fmin(y + gap, 0.0));
        dx[car->ndof + iy] += (2.0 * fy * s + fl) * car->inv_m[w];
        dx[car->ndof + ip] += (-2.0 * b0 * fx * s) * car->inv_i[w];
    }
}

static void rhs(const Car *car, const double *x, const double *F, double *dx) {
    int j, i;
    for (j = 0; j < car->nx; j++) {
        const double *a = car->Am + (size_t)j * car->nx, *af = car->Af + (size_t)j * car->nd;
        double s = 0.0;
        for (i = 0; i < car->nx; i++) s += a[i] * x[i];
        for (i = 0; i < car->nd; i++) s += af[i] * F[i];
        dx[j] = s;
    }
    contact(car, x, dx);
}

/* m RK4 steps over h with the forces linear from F0 to F1; k1 of the first step given in dx0 */
static void advance(const Car *car, double *x, const double *F0, const double *F1, double h, int m,
                    const double *dx0) {
    double k1[MAXX], k2[MAXX], k3[MAXX], k4[MAXX], xs[MAXX], Fa[MAXD], Fb[MAXD], Fc[MAXD];
    double hs = h / m;
    int j, i, nx = car->nx, nd = car->nd;
    for (j = 0; j < m; j++) {
        double t0 = j * hs / h, tm = (j + 0.5) * hs / h, t1 = (j + 1) * hs / h;
        for (i = 0; i < nd; i++) {
            Fa[i] = F0[i] + (F1[i] - F0[i]) * t0;
            Fb[i] = F0[i] + (F1[i] - F0[i]) * tm;
            Fc[i] = F0[i] + (F1[i] - F0[i]) * t1;
        }
        if (j == 0) for (i = 0; i < nx; i++) k1[i] = dx0[i];
        else rhs(car, x, Fa, k1);
        for (i = 0; i < nx; i++) xs[i] = x[i] + 0.5 * hs * k1[i];
        rhs(car, xs, Fb, k2);
        for (i = 0; i < nx; i++) xs[i] = x[i] + 0.5 * hs * k2[i];
        rhs(car, xs, Fb, k3);
        for (i = 0; i < nx; i++) xs[i] = x[i] + hs * k3[i];
        rhs(car, xs, Fc, k4);
        for (i = 0; i < nx; i++) x[i] += (hs / 6.0) * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
}

int nonlinear_vehicle_run(int n, int m, int nx, int nd, int nw, int nb, const double *Am, const double *Af,
                          const double *E, const double *c, const int *wi, const double *inv_m,
                          const double *inv_i, double h, void **set_real, void **set_der, void **do_step,
                          void **get_real, void **comp, const unsigned int *vr, double *X, double *F,
                          int *failed_step, int *failed_damper) {
    Car car;
    double x[MAXX], dx[MAXX], in[2], acc;
    const int order1 = 1;
    int k, i, j, st, ndof = nx / 2;
    if (nd > MAXD || nx > MAXX || m < 1) return 3;
    car.nx = nx; car.nd = nd; car.nw = nw; car.ndof = ndof; car.nb = nb;
    car.Am = Am; car.Af = Af; car.inv_m = inv_m; car.inv_i = inv_i; car.c = c; car.wi = wi;
    for (j = 0; j < nx; j++) x[j] = X[j];
    for (k = 0; k < n; k++) {
        const double *Fk = F + (size_t)k * nd;
        double *Fn = F + (size_t)(k + 1) * nd;
        double t = k * h;
        rhs(&car, x, Fk, dx);
        for (i = 0; i < nd; i++) {
            const double *e = E + (size_t)i * ndof;
            const unsigned int *v = vr + 3 * i;
            in[0] = 0.0; in[1] = 0.0; acc = 0.0;
            for (j = 0; j < ndof; j++) { in[0] += e[j] * x[j]; in[1] += e[j] * x[ndof + j]; acc += e[j] * dx[ndof + j]; }
            st = ((SetReal)set_real[i])(comp[i], v, 2, in);
            if (st <= 1 && set_der[i]) st = ((SetDer)set_der[i])(comp[i], v + 1, 1, &order1, &acc);
            if (st <= 1) st = ((DoStep)do_step[i])(comp[i], t, h, 1);
            if (st <= 1) st = ((GetReal)get_real[i])(comp[i], v + 2, 1, Fn + i);
            if (st > 1) { *failed_step = k; *failed_damper = i; return st; }
        }
        advance(&car, x, Fk, Fn, h, m, dx);
        for (j = 0; j < nx; j++) X[(size_t)(k + 1) * nx + j] = x[j];
    }
    return 0;
}
