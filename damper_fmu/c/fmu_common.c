/* The FMI-independent part of the native FMUs, written once for fmi2_damper.c and fmi3_damper.c.
 *
 * Each wrapper includes this file (everything here is static, so a binary exports the wrapper's fmi2*
 * or fmi3* functions only; this FMU's GUID and start values come from damper_fmu_values.c, hidden) after
 * defining
 *   FMI            "fmi2" or "fmi3": the prefix of the function names in messages;
 *   STATE_MAGIC    the first word of a serialized FMU state (refuses another version's state);
 *   Callbacks      the type of what the importer passes to instantiate (logger and environment);
 *   VR_INPUT_INTERPOLATION, VR_THERMAL_SOURCE  the value references of the two integer settings;
 * and defines, after it, error_message(): the error in the wrapper's logger, category
 * logStatusError. Here: the kernel (damper_kernel.c) and the generated headers, the instance and
 * its snapshot (everything a state roll-back restores), parameter and input checks, the initial
 * outputs, the variables' values, initialization, the step, and the FMU state and its
 * serialization. The FMU's life cycle, value references and messages are described in the
 * wrappers.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the kernel in this translation unit, with internal linkage: a binary exports the FMI functions
   only, and several FMUs' sources compile into one program without clashes */
#define DK_API static
#define DK_EMBEDDED
#include "damper_kernel.c"
#include "damper_params.h"
#include "damper_fmu_config.h"

/* This FMU's GUID and start values, defined in damper_fmu_values.c (generated per FMU: the rest of the
   sources is the same for every FMU of a model and FMI version, so one compiled object serves them all).
   Named after the model identifier and the FMI version (damper_fmu_config.h), hidden from the binary's
   exported symbols. */
DK_HIDDEN extern const char DK_GUID[];
DK_HIDDEN extern const double DK_START_VALUES[];
/* max_internal_step [s], internal_tolerance [-], stroke_limit [m], velocity_limit [m/s] */
DK_HIDDEN extern const double DK_START_SETTINGS[4];
DK_HIDDEN extern const int DK_START_INPUT_INTERPOLATION;

#if DK_MODEL_KIND == DK_LUMPED
#define NPAR DK_LUMPED_N
#define SPECS DK_PARAMS_LUMPED
#define NDIAG DK_LUMPED_NDIAG
#elif DK_MODEL_KIND == DK_MAXWELL
#define NPAR DK_MAXWELL_N
#define SPECS DK_PARAMS_MAXWELL
#define NDIAG DK_MAXWELL_NDIAG
#elif DK_MODEL_KIND == DK_TWOCHAMBER
#define NPAR DK_TWOCHAMBER_N
#define SPECS DK_PARAMS_TWOCHAMBER
#define NDIAG DK_TWOCHAMBER_NDIAG
#else
#define NPAR DK_MAXWELL_TABLE_N
#define SPECS DK_PARAMS_MAXWELL_TABLE
#define NDIAG DK_MAXWELL_TABLE_NDIAG
#endif

/* models with the effect elements (thermal drift: the oil_temperature input, thermal_source) */
#define HAS_EFFECTS (DK_MODEL_KIND == DK_LUMPED || DK_MODEL_KIND == DK_TWOCHAMBER)

/* value references of the Real (FMI 2.0) / Float64 (FMI 3.0) variables, the same in both */
#define VR_STROKE 0
#define VR_VELOCITY 1
#define VR_FORCE 2
#define VR_TEMPERATURE 3
#define VR_DIAG 10
#define VR_MAX_STEP 50
#define VR_TOLERANCE 51
#define VR_STROKE_LIMIT 52
#define VR_VELOCITY_LIMIT 53
#define VR_PARAM 100

enum { ST_INSTANTIATED, ST_INIT, ST_STEP, ST_TERMINATED, ST_ERROR };

/* Everything a rollback must restore (get/set FMU state). accel: the stroke acceleration a master
   set for the next step (FMI 2.0 input derivatives; FMI 3.0 has none, accel_set stays 0). */
typedef struct {
    double p[NPAR];
    double max_step, tolerance, stroke_limit, velocity_limit;
    int input_interpolation, thermal_source;
    double stroke, velocity, temperature, accel;
    int accel_set, dirty, state;
    double time;
    DkSim sim;
} Snapshot;

typedef struct {
    Callbacks cb;
    char *name;
    int logging;
    Snapshot s;
} Instance;

/* an error with its reason through the importer's logger (defined by the wrapper); fmt holds one %s */
static void error_message(Instance *c, const char *fmt, const char *detail);

static void defaults(Snapshot *s) {
    int i;
    memset(s, 0, sizeof *s);
    for (i = 0; i < NPAR; i++) s->p[i] = DK_START_VALUES[i];
    s->max_step = DK_START_SETTINGS[0];
    s->tolerance = DK_START_SETTINGS[1];
    s->stroke_limit = DK_START_SETTINGS[2];
    s->velocity_limit = DK_START_SETTINGS[3];
    s->input_interpolation = DK_START_INPUT_INTERPOLATION;
    s->thermal_source = 0;
    s->temperature = 20.0;
    s->accel = 0.0;
    s->dirty = 1;
    s->state = ST_INSTANTIATED;
    dk_sim_clear(&s->sim);
}

/* ---- instance ------------------------------------------------------------------------------ */

static Instance *instance_new(const char *name, const Callbacks *cb, int logging) {
    Instance *c = (Instance *)calloc(1, sizeof *c);
    if (!c) return NULL;
    c->cb = *cb;
    c->name = (char *)malloc(strlen(name ? name : "") + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, name ? name : "");
    c->logging = logging;
    defaults(&c->s);
    return c;
}

static void instance_free(Instance *c) {
    if (!c) return;
    dk_sim_free(&c->s.sim);
    free(c->name);
    free(c);
}

static void instance_reset(Instance *c) {
    dk_sim_free(&c->s.sim);
    defaults(&c->s);
}

/* ---- checks, model, initial outputs -------------------------------------------------------- */

static int check_inputs(Instance *c) {
    Snapshot *s = &c->s;
    char d[256];
    if (!dk_finite(s->stroke) || !dk_finite(s->velocity)) {
        snprintf(d, sizeof d, "stroke = %g m, stroke_velocity = %g m/s", s->stroke, s->velocity);
        error_message(c, "non-finite input (%s)", d);
        return 1;
    }
    if (fabs(s->stroke) > s->stroke_limit || fabs(s->velocity) > s->velocity_limit) {
        snprintf(d, sizeof d, "stroke = %g m (limit %g m), stroke_velocity = %g m/s (limit %g m/s); "
                 "inputs are SI: a stroke in mm or a velocity in mm/s gives this. Raise stroke_limit / "
                 "velocity_limit if the values are real", s->stroke, s->stroke_limit, s->velocity, s->velocity_limit);
        error_message(c, "input out of range: %s", d);
        return 1;
    }
    if (HAS_EFFECTS && s->thermal_source && !dk_finite(s->temperature)) {
        error_message(c, "non-finite input: %s", "oil_temperature");
        return 1;
    }
    return 0;
}

/* the model from the parameters, at initialization or after a change of a tunable parameter */
static int build(Instance *c) {
    Snapshot *s = &c->s;
    if (s->state == ST_INIT) {
        dk_sim_free(&s->sim);
        dk_sim_clear(&s->sim);
        if (dk_sim_setup(&s->sim, DK_MODEL_KIND, s->p, NPAR, s->max_step, s->tolerance, s->input_interpolation)) {
            error_message(c, "invalid parameters: %s", s->sim.msg);
            return 1;
        }
    } else {
        DkModel m;
        char msg[512];
        int was_active = s->sim.model.effects_active;
        if (dk_model_init(&m, DK_MODEL_KIND, s->p, NPAR, msg, sizeof msg)) {
            error_message(c, "invalid parameters: %s", msg);
            return 1;
        }
        s->sim.model = m;
        if (m.effects_active && !was_active) {
            s->sim.e.x_eff = s->sim.x1; s->sim.e.engaged = 1; s->sim.e.temperature = m.t_ref;
            s->sim.e.time = 0.0; s->sim.e.hist_len = 0; s->sim.e.hist_head = 0;
            s->sim.e.x_seen = s->sim.x1; s->sim.e.v_seen = s->sim.v1; s->sim.e.z = 0.0;
        }
    }
    s->dirty = 0;
    return 0;
}

/* The initial outputs (force and element outputs) before ExitInitializationMode, from the
   parameters and inputs set so far: what the first doStep starts from (dk_sim_initialize), so a
   master that passes initial outputs on (an SSP master, OMSimulator) starts from the right force. */
static int initial_outputs(Instance *c, double *force, double *diag) {
    Snapshot *s = &c->s;
    DkSim *sim;
    if (check_inputs(c)) return 1;
    sim = (DkSim *)calloc(1, sizeof *sim);
    if (!sim) { error_message(c, "%s", "out of memory for the initial outputs"); return 1; }
    dk_sim_clear(sim);
    if (dk_sim_setup(sim, DK_MODEL_KIND, s->p, NPAR, s->max_step, s->tolerance, s->input_interpolation)) {
        error_message(c, "invalid parameters: %s", sim->msg);
        free(sim);
        return 1;
    }
    sim->has_temperature = HAS_EFFECTS && s->thermal_source;
    sim->temperature_input = s->temperature;
    if (dk_sim_initialize(sim, s->stroke, s->velocity, s->time)) {
        error_message(c, "initial outputs: %s", sim->msg);
        dk_sim_free(sim);
        free(sim);
        return 1;
    }
    *force = sim->force;
    dk_diagnostics(sim, diag);
    dk_sim_free(sim);
    free(sim);
    return 0;
}

/* ---- variables ----------------------------------------------------------------------------- */

static int is_param(unsigned vr) { return vr >= VR_PARAM && vr < VR_PARAM + NPAR; }

static int is_output(unsigned vr) { return vr == VR_FORCE || (vr >= VR_DIAG && vr < VR_DIAG + NDIAG); }

/* fixed parameters (the table abscissae) may not change after initialisation */
static int is_fixed_param(int i) { return SPECS[i].fixed; }

/* the value of a Real/Float64 variable other than time; force and diag: the outputs (used when vr
   is an output). 0, or 2: no such variable */
static int get_float(const Instance *c, unsigned r, double force, const double *diag, double *value) {
    const Snapshot *s = &c->s;
    if (r == VR_STROKE) *value = s->stroke;
    else if (r == VR_VELOCITY) *value = s->velocity;
    else if (r == VR_FORCE) *value = force;
    else if (r == VR_TEMPERATURE && HAS_EFFECTS) *value = s->temperature;
    else if (r >= VR_DIAG && r < VR_DIAG + NDIAG) *value = diag[r - VR_DIAG];
    else if (r == VR_MAX_STEP) *value = s->max_step;
    else if (r == VR_TOLERANCE) *value = s->tolerance;
    else if (r == VR_STROKE_LIMIT) *value = s->stroke_limit;
    else if (r == VR_VELOCITY_LIMIT) *value = s->velocity_limit;
    else if (is_param(r)) *value = s->p[r - VR_PARAM];
    else return 2;
    return 0;
}

/* set a Real/Float64 variable: 0, 1 refused (reported), or 2: no such settable variable */
static int set_float(Instance *c, unsigned r, double value) {
    Snapshot *s = &c->s;
    int after_init = s->state >= ST_STEP;
    if (r == VR_STROKE) s->stroke = value;
    else if (r == VR_VELOCITY) s->velocity = value;
    else if (r == VR_TEMPERATURE && HAS_EFFECTS) s->temperature = value;
    else if (r == VR_MAX_STEP || r == VR_TOLERANCE || r == VR_STROKE_LIMIT || r == VR_VELOCITY_LIMIT) {
        if (after_init) {
            error_message(c, "%s", "the integrator settings and input limits are fixed parameters: "
                                   "set them before " FMI "ExitInitializationMode");
            return 1;
        }
        if (r == VR_MAX_STEP) s->max_step = value;
        else if (r == VR_TOLERANCE) s->tolerance = value;
        else if (r == VR_STROKE_LIMIT) s->stroke_limit = value;
        else s->velocity_limit = value;
    } else if (is_param(r)) {
        int k = (int)(r - VR_PARAM);
        if (after_init && is_fixed_param(k)) {
            error_message(c, "%s is a fixed parameter: set it before " FMI "ExitInitializationMode", SPECS[k].name);
            return 1;
        }
        s->p[k] = value;
        s->dirty = 1;
    } else return 2;
    return 0;
}

/* the value of an Integer/Int32 variable: 0, or 2: no such variable */
static int get_integer(const Instance *c, unsigned r, int *value) {
    if (r == VR_INPUT_INTERPOLATION) *value = c->s.input_interpolation;
    else if (r == VR_THERMAL_SOURCE && HAS_EFFECTS) *value = c->s.thermal_source;
    else return 2;
    return 0;
}

/* set an Integer/Int32 variable: 0, 1 refused (reported), or 2: no such variable */
static int set_integer(Instance *c, unsigned r, int value) {
    if (c->s.state >= ST_STEP) {
        error_message(c, "%s", "input_interpolation and thermal_source are fixed: set them before "
                               FMI "ExitInitializationMode");
        return 1;
    }
    if (r == VR_INPUT_INTERPOLATION) {
        if (value != 0 && value != 1) { error_message(c, "%s", "input_interpolation must be 0 or 1"); return 1; }
        c->s.input_interpolation = value;
    } else if (r == VR_THERMAL_SOURCE && HAS_EFFECTS) {
        if (value != 0 && value != 1) { error_message(c, "%s", "thermal_source must be 0 or 1"); return 1; }
        c->s.thermal_source = value;
    } else return 2;
    return 0;
}

/* ---- initialization and steps -------------------------------------------------------------- */

/* ExitInitializationMode: the model from the parameters and the first state; 0, or 1 (reported;
   the instance is in the error state, except when called outside initialization mode) */
static int exit_initialization(Instance *c) {
    Snapshot *s = &c->s;
    if (s->state != ST_INIT) {
        error_message(c, "%s", FMI "ExitInitializationMode outside initialization mode");
        return 1;
    }
    if (!(s->stroke_limit > 0.0) || !(s->velocity_limit > 0.0)) {
        s->state = ST_ERROR;
        error_message(c, "%s", "stroke_limit and velocity_limit must be positive");
        return 1;
    }
    if (build(c) || check_inputs(c)) { s->state = ST_ERROR; return 1; }
    s->sim.has_temperature = HAS_EFFECTS && s->thermal_source;
    s->sim.temperature_input = s->temperature;
    if (dk_sim_initialize(&s->sim, s->stroke, s->velocity, s->time)) {
        s->state = ST_ERROR;
        error_message(c, "initialisation failed: %s", s->sim.msg);
        return 1;
    }
    s->state = ST_STEP;
    return 0;
}

#define STEP_OK 0
#define STEP_REFUSED 1    /* not in step mode or a bad step size: nothing changed */
#define STEP_BAD_INPUT 2  /* invalid parameters or inputs */
#define STEP_FAILED 3     /* the kernel's step failed */

/* one communication step from t of size h; accel: the stroke acceleration, or NULL (estimated) */
static int do_step(Instance *c, double t, double h, const double *accel) {
    Snapshot *s = &c->s;
    char d[600];
    if (s->state != ST_STEP) {
        error_message(c, "%s", s->state == ST_ERROR ? "the FMU is in an error state (see the earlier message); "
                                                      "reset or re-instantiate it"
                                                    : FMI "DoStep before " FMI "ExitInitializationMode");
        return STEP_REFUSED;
    }
    if (!(h > 0.0)) {
        snprintf(d, sizeof d, "%g", h);
        error_message(c, "communication step size must be positive, got %s s", d);
        return STEP_REFUSED;
    }
    if ((s->dirty && build(c)) || check_inputs(c)) return STEP_BAD_INPUT;
    s->sim.has_temperature = HAS_EFFECTS && s->thermal_source;
    s->sim.temperature_input = s->temperature;
    if (dk_sim_step(&s->sim, h, s->stroke, s->velocity, accel)) {
        snprintf(d, sizeof d, "step at t = %.9g s failed: %s", t, s->sim.msg);
        error_message(c, "%s", d);
        return STEP_FAILED;
    }
    s->time = t + h;
    return STEP_OK;
}

/* ---- FMU state ----------------------------------------------------------------------------- */
/* The FMI functions never call one another: in a host that loads several FMUs with RTLD_GLOBAL, a
   call to an exported FMI function may resolve to another FMU's (interposition). */

/* copy the instance's state into *state (allocated when NULL); 0, or 1 (reported) */
static int state_get(Instance *c, void **state) {
    Snapshot *snap = (Snapshot *)*state;
    DkSim keep;
    if (!snap) {
        snap = (Snapshot *)calloc(1, sizeof *snap);
        if (!snap) { error_message(c, "%s", "out of memory for the FMU state"); return 1; }
    }
    keep = snap->sim;
    *snap = c->s;
    snap->sim = keep;
    if (dk_sim_copy(&snap->sim, &c->s.sim)) { error_message(c, "%s", "out of memory for the FMU state"); return 1; }
    *state = snap;
    return 0;
}

/* restore the instance from a state; 0, or 1 (reported) */
static int state_set(Instance *c, const Snapshot *snap) {
    DkSim keep = c->s.sim;
    c->s = *snap;
    c->s.sim = keep;
    if (dk_sim_copy(&c->s.sim, &snap->sim)) {
        error_message(c, "%s", "out of memory restoring the FMU state");
        return 1;
    }
    return 0;
}

static void state_free(void **state) {
    if (state && *state) {
        Snapshot *snap = (Snapshot *)*state;
        dk_sim_free(&snap->sim);
        free(snap);
        *state = NULL;
    }
}

static size_t serialized_size(const Snapshot *snap) {
    return 2 * sizeof(int) + sizeof(Snapshot) + 2 * (size_t)snap->sim.e.hist_len * sizeof(double);
}

/* fn: the calling function's name, for the messages; 0, or 1 (reported) */
static int state_serialize(Instance *c, const Snapshot *snap, unsigned char *buf, size_t size, const char *fn) {
    int head[2] = {STATE_MAGIC, (int)sizeof(Snapshot)}, i;
    unsigned char *p = buf;
    if (!snap) { error_message(c, "%s: no FMU state given", fn); return 1; }
    if (size < serialized_size(snap)) { error_message(c, "%s: buffer too small", fn); return 1; }
    memcpy(p, head, sizeof head); p += sizeof head;
    memcpy(p, snap, sizeof *snap); p += sizeof *snap;
    for (i = 0; i < snap->sim.e.hist_len; i++) {
        const double *q = snap->sim.e.hist + 2 * ((snap->sim.e.hist_head + i) % snap->sim.e.hist_cap);
        memcpy(p, q, 2 * sizeof(double)); p += 2 * sizeof(double);
    }
    return 0;
}

/* a state from its serialized bytes into *state (a state given there is freed first); 0, or 1 (reported) */
static int state_deserialize(Instance *c, const unsigned char *buf, size_t size, void **state) {
    int head[2];
    Snapshot *snap;
    size_t nh;
    if (size < sizeof head + sizeof(Snapshot)) { error_message(c, "%s", "serialized FMU state too short"); return 1; }
    memcpy(head, buf, sizeof head);
    if (head[0] != STATE_MAGIC || head[1] != (int)sizeof(Snapshot)) {
        error_message(c, "%s", "serialized FMU state is not from this FMU build");
        return 1;
    }
    if (*state) state_free(state);
    snap = (Snapshot *)calloc(1, sizeof *snap);
    if (!snap) { error_message(c, "%s", "out of memory for the FMU state"); return 1; }
    memcpy(snap, buf + sizeof head, sizeof *snap);
    nh = (size_t)snap->sim.e.hist_len;
    if (size < sizeof head + sizeof(Snapshot) + 2 * nh * sizeof(double)) {
        free(snap);
        error_message(c, "%s", "serialized FMU state truncated");
        return 1;
    }
    snap->sim.e.hist = NULL; snap->sim.e.hist_cap = 0; snap->sim.e.hist_head = 0;
    if (nh) {
        snap->sim.e.hist = (double *)malloc(2 * nh * sizeof(double));
        if (!snap->sim.e.hist) { free(snap); error_message(c, "%s", "out of memory for the FMU state"); return 1; }
        memcpy(snap->sim.e.hist, buf + sizeof head + sizeof(Snapshot), 2 * nh * sizeof(double));
        snap->sim.e.hist_cap = (int)nh;
    }
    *state = snap;
    return 0;
}
