/* FMI 3.0 co-simulation interface of the damper models (native FMU).
 *
 * The FMI 3.0 twin of fmi2_damper.c, around the same kernel (damper_kernel.c, included here: one
 * translation unit, compile this file alone) with the same generated headers: damper_fmu_config.h
 * (model kind, instantiation token, start values of the settings) and damper_params.h (the
 * parameters, from damper_fmu/parameters.py). Same life cycle, same checks, same messages, same
 * calls into the kernel in the same order, so the forces equal the FMI 2.0 FMU's bit for bit
 * (tests/test_fmi3.py). What FMI 3.0 changes:
 *
 * - one value-reference space for all types: the Float64 variables keep the FMI 2.0 Real value
 *   references (0 stroke, 1 stroke_velocity, 2 force, 3 oil_temperature, 10.. internal element
 *   outputs, 50..53 settings, 100 + i the i-th model parameter); the Int32 settings move from FMI
 *   2.0 Integer 0 and 1 to 60 input_interpolation and 61 thermal_source; 4 is the independent
 *   variable time (damper_fmu/model_description.py: FMI3_VR);
 * - no input derivatives (FMI 3.0 has no fmi3SetRealInputDerivatives): the acceleration of the
 *   stroke within a step is always estimated from the last velocity samples, as in the FMI 2.0 FMU
 *   when the master sets no derivatives (fmpy's simulate_fmu, most masters);
 * - fmi3DoStep reports through its out-arguments: never an event, never a request to terminate,
 *   never an early return; lastSuccessfulTime is the end of the step, or its start after an error;
 * - an error (bad parameters, a bad input, a failed step) puts the instance in an error state in
 *   which only fmi3Reset, fmi3Terminate, fmi3FreeInstance and the getters are useful (FMI 3.0,
 *   fmi3Error).
 *
 * Errors return fmi3Error with a message through logMessage, category logStatusError, whatever the
 * logging setting. Functions of other interface types (model exchange, scheduled execution, event
 * mode, clocks, configuration mode, derivatives) return fmi3Error with a message saying why.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* FMI3_FUNCTION_PREFIX (source-code import of several FMUs into one program) is honoured by the
   standard header; everything else in this translation unit is static, the kernel included. */
#include "fmi3Functions.h"

#define DK_API static
#define DK_EMBEDDED
#include "damper_kernel.c"
#include "damper_params.h"
#include "damper_fmu_config.h"

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

#define HAS_EFFECTS (DK_MODEL_KIND == DK_LUMPED || DK_MODEL_KIND == DK_TWOCHAMBER)

#define VR_STROKE 0
#define VR_VELOCITY 1
#define VR_FORCE 2
#define VR_TEMPERATURE 3
#define VR_TIME 4
#define VR_DIAG 10
#define VR_MAX_STEP 50
#define VR_TOLERANCE 51
#define VR_STROKE_LIMIT 52
#define VR_VELOCITY_LIMIT 53
#define VR_INPUT_INTERPOLATION 60
#define VR_THERMAL_SOURCE 61
#define VR_PARAM 100

enum { ST_INSTANTIATED, ST_INIT, ST_STEP, ST_TERMINATED, ST_ERROR };

/* Everything a rollback must restore (fmi3GetFMUState / fmi3SetFMUState). */
typedef struct {
    double p[NPAR];
    double max_step, tolerance, stroke_limit, velocity_limit;
    int input_interpolation, thermal_source;
    double stroke, velocity, temperature;
    int dirty, state;
    double time;
    DkSim sim;
} Snapshot;

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    char *name;
    int logging;
    Snapshot s;
} Instance;

/* The message is prefixed with the instance name (FMI 3.0's logger has no instance argument). */
static void logmsg(Instance *c, fmi3Status status, const char *category, const char *fmt, ...) {
    char buf[1024];
    int n;
    va_list ap;
    if (!c || !c->log) return;
    if (status == fmi3OK && !c->logging) return;
    n = snprintf(buf, sizeof buf, "%s: ", c->name);
    if (n < 0 || (size_t)n >= sizeof buf) n = 0;
    va_start(ap, fmt);
    vsnprintf(buf + n, sizeof buf - (size_t)n, fmt, ap);
    va_end(ap);
    c->log(c->env, status, category, buf);
}

static fmi3Status fail(Instance *c, const char *fmt, const char *detail) {
    logmsg(c, fmi3Error, "logStatusError", fmt, detail);
    return fmi3Error;
}

/* an error the instance cannot continue from (FMI 3.0: fmi3Error) */
static fmi3Status fail_state(Instance *c, const char *fmt, const char *detail) {
    c->s.state = ST_ERROR;
    return fail(c, fmt, detail);
}

static void defaults(Snapshot *s) {
    int i;
    memset(s, 0, sizeof *s);
    for (i = 0; i < NPAR; i++) s->p[i] = SPECS[i].start;
    s->max_step = DK_START_MAX_STEP;
    s->tolerance = DK_START_TOLERANCE;
    s->stroke_limit = DK_START_STROKE_LIMIT;
    s->velocity_limit = DK_START_VELOCITY_LIMIT;
    s->input_interpolation = DK_START_INPUT_INTERPOLATION;
    s->thermal_source = 0;
    s->temperature = 20.0;
    s->dirty = 1;
    s->state = ST_INSTANTIATED;
    dk_sim_clear(&s->sim);
}

/* ---- inquiry ------------------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[]) {
    (void)n; (void)cats;
    if (!c) return fmi3Error;
    ((Instance *)c)->logging = on;
    return fmi3OK;
}

/* ---- life cycle ---------------------------------------------------------------------------- */

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resourcePath,
                                         fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed, const fmi3ValueReference required[],
                                         size_t nRequired, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance *c;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)required; (void)nRequired;
    (void)intermediateUpdate; /* providesIntermediateUpdate="false": never called */
    if (eventModeUsed) {
        if (logMessage)
            logMessage(env, fmi3Error, "logStatusError",
                       "eventModeUsed = true, but this FMU has no event mode (hasEventMode=\"false\")");
        return NULL;
    }
    if (!token || strcmp(token, DK_GUID) != 0) {
        if (logMessage)
            logMessage(env, fmi3Error, "logStatusError",
                       "instantiation token does not match this binary's " DK_GUID
                       " (modelDescription.xml and binary from different builds)");
        return NULL;
    }
    c = (Instance *)calloc(1, sizeof *c);
    if (!c) return NULL;
    c->env = env;
    c->log = logMessage;
    c->name = (char *)malloc(strlen(name ? name : "") + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, name ? name : "");
    c->logging = logging;
    defaults(&c->s);
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resourcePath,
                                          fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback logMessage) {
    (void)name; (void)token; (void)resourcePath; (void)visible; (void)logging;
    if (logMessage) logMessage(env, fmi3Error, "logStatusError", "this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resourcePath,
                                               fmi3Boolean visible, fmi3Boolean logging,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lock, fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)resourcePath; (void)visible; (void)logging; (void)clockUpdate; (void)lock;
    (void)unlock;
    if (logMessage) logMessage(env, fmi3Error, "logStatusError", "this FMU supports co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance comp) {
    Instance *c = (Instance *)comp;
    if (!c) return;
    dk_sim_free(&c->s.sim);
    free(c->name);
    free(c);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance comp, fmi3Boolean tolDefined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stopDefined, fmi3Float64 stop) {
    Instance *c = (Instance *)comp;
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    if (!c) return fmi3Error;
    if (c->s.state != ST_INSTANTIATED)
        return fail(c, "%s", "fmi3EnterInitializationMode: only after instantiation or fmi3Reset");
    c->s.time = start;
    c->s.state = ST_INIT;
    return fmi3OK;
}

static int check_inputs(Instance *c) {
    Snapshot *s = &c->s;
    char d[256];
    if (!dk_finite(s->stroke) || !dk_finite(s->velocity)) {
        snprintf(d, sizeof d, "stroke = %g m, stroke_velocity = %g m/s", s->stroke, s->velocity);
        fail(c, "non-finite input (%s)", d);
        return 1;
    }
    if (fabs(s->stroke) > s->stroke_limit || fabs(s->velocity) > s->velocity_limit) {
        snprintf(d, sizeof d, "stroke = %g m (limit %g m), stroke_velocity = %g m/s (limit %g m/s); "
                 "inputs are SI: a stroke in mm or a velocity in mm/s gives this. Raise stroke_limit / "
                 "velocity_limit if the values are real", s->stroke, s->stroke_limit, s->velocity, s->velocity_limit);
        fail(c, "input out of range: %s", d);
        return 1;
    }
    if (HAS_EFFECTS && s->thermal_source && !dk_finite(s->temperature)) {
        fail(c, "non-finite input: %s", "oil_temperature");
        return 1;
    }
    return 0;
}

/* as fmi2_damper.c's build(): the model from the parameters, at initialization or after a change of
   a tunable parameter */
static int build(Instance *c) {
    Snapshot *s = &c->s;
    if (s->state == ST_INIT) {
        dk_sim_free(&s->sim);
        dk_sim_clear(&s->sim);
        if (dk_sim_setup(&s->sim, DK_MODEL_KIND, s->p, NPAR, s->max_step, s->tolerance, s->input_interpolation)) {
            fail(c, "invalid parameters: %s", s->sim.msg);
            return 1;
        }
    } else {
        DkModel m;
        char msg[512];
        int was_active = s->sim.model.effects_active;
        if (dk_model_init(&m, DK_MODEL_KIND, s->p, NPAR, msg, sizeof msg)) {
            fail(c, "invalid parameters: %s", msg);
            return 1;
        }
        s->sim.model = m;
        if (m.effects_active && !was_active) {
            s->sim.e.x_eff = s->sim.x1; s->sim.e.engaged = 1; s->sim.e.temperature = m.t_ref;
            s->sim.e.time = 0.0; s->sim.e.hist_len = 0; s->sim.e.hist_head = 0;
        }
    }
    s->dirty = 0;
    return 0;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance comp) {
    Instance *c = (Instance *)comp;
    Snapshot *s;
    if (!c) return fmi3Error;
    s = &c->s;
    if (s->state != ST_INIT) return fail(c, "%s", "fmi3ExitInitializationMode outside initialization mode");
    if (!(s->stroke_limit > 0.0) || !(s->velocity_limit > 0.0))
        return fail_state(c, "%s", "stroke_limit and velocity_limit must be positive");
    if (build(c) || check_inputs(c)) { s->state = ST_ERROR; return fmi3Error; }
    s->sim.has_temperature = HAS_EFFECTS && s->thermal_source;
    s->sim.temperature_input = s->temperature;
    if (dk_sim_initialize(&s->sim, s->stroke, s->velocity, s->time))
        return fail_state(c, "initialisation failed: %s", s->sim.msg);
    s->state = ST_STEP;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance comp) {
    Instance *c = (Instance *)comp;
    if (!c) return fmi3Error;
    c->s.state = ST_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance comp) {
    Instance *c = (Instance *)comp;
    if (!c) return fmi3Error;
    dk_sim_free(&c->s.sim);
    defaults(&c->s);
    return fmi3OK;
}

/* ---- variables ----------------------------------------------------------------------------- */

static int is_param(fmi3ValueReference vr) { return vr >= VR_PARAM && vr < VR_PARAM + NPAR; }

/* the initial outputs before fmi3ExitInitializationMode (as fmi2_damper.c) */
static int initial_outputs(Instance *c, double *force, double *diag) {
    Snapshot *s = &c->s;
    DkSim *sim;
    if (check_inputs(c)) return 1;
    sim = (DkSim *)calloc(1, sizeof *sim);
    if (!sim) { fail(c, "%s", "out of memory for the initial outputs"); return 1; }
    dk_sim_clear(sim);
    if (dk_sim_setup(sim, DK_MODEL_KIND, s->p, NPAR, s->max_step, s->tolerance, s->input_interpolation)) {
        fail(c, "invalid parameters: %s", sim->msg);
        free(sim);
        return 1;
    }
    sim->has_temperature = HAS_EFFECTS && s->thermal_source;
    sim->temperature_input = s->temperature;
    if (dk_sim_initialize(sim, s->stroke, s->velocity, s->time)) {
        fail(c, "initial outputs: %s", sim->msg);
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

/* scalar variables only: one value per value reference */
static int count_ok(Instance *c, const char *fn, size_t nvr, size_t nvalues) {
    char d[160];
    if (nvr == nvalues) return 1;
    snprintf(d, sizeof d, "%s: %lu values for %lu value references (every variable is a scalar)", fn,
             (unsigned long)nvalues, (unsigned long)nvr);
    fail(c, "%s", d);
    return 0;
}

static fmi3Status unknown_vr(Instance *c, const char *fn, fmi3ValueReference r) {
    char d[160];
    snprintf(d, sizeof d, "%s: unknown value reference %u", fn, (unsigned)r);
    return fail(c, "%s", d);
}

fmi3Status fmi3GetFloat64(fmi3Instance comp, const fmi3ValueReference vr[], size_t n, fmi3Float64 value[],
                          size_t nValues) {
    Instance *c = (Instance *)comp;
    size_t i;
    double diag[DK_NDIAG_MAX], force0 = 0.0;
    int have_diag = 0;
    if (!c) return fmi3Error;
    if (!count_ok(c, "fmi3GetFloat64", n, nValues)) return fmi3Error;
    for (i = 0; i < n; i++) {
        fmi3ValueReference r = vr[i];
        Snapshot *s = &c->s;
        if ((r == VR_FORCE || (r >= VR_DIAG && r < VR_DIAG + NDIAG)) && !have_diag) {
            /* outputs: of the last step, or the initial ones before the first */
            if (s->state == ST_STEP || s->state == ST_TERMINATED) {
                force0 = s->sim.force;
                dk_diagnostics(&s->sim, diag);
            } else if (s->state == ST_ERROR) {
                return fail(c, "%s", "fmi3GetFloat64: no outputs in the error state (see the earlier message)");
            } else if (initial_outputs(c, &force0, diag)) {
                return fmi3Error;
            }
            have_diag = 1;
        }
        if (r == VR_STROKE) value[i] = s->stroke;
        else if (r == VR_VELOCITY) value[i] = s->velocity;
        else if (r == VR_FORCE) value[i] = force0;
        else if (r == VR_TEMPERATURE && HAS_EFFECTS) value[i] = s->temperature;
        else if (r == VR_TIME) value[i] = s->time;
        else if (r >= VR_DIAG && r < VR_DIAG + NDIAG) value[i] = diag[r - VR_DIAG];
        else if (r == VR_MAX_STEP) value[i] = s->max_step;
        else if (r == VR_TOLERANCE) value[i] = s->tolerance;
        else if (r == VR_STROKE_LIMIT) value[i] = s->stroke_limit;
        else if (r == VR_VELOCITY_LIMIT) value[i] = s->velocity_limit;
        else if (is_param(r)) value[i] = s->p[r - VR_PARAM];
        else return unknown_vr(c, "fmi3GetFloat64", r);
    }
    return fmi3OK;
}

static int is_fixed_param(int i) { return SPECS[i].fixed; }

fmi3Status fmi3SetFloat64(fmi3Instance comp, const fmi3ValueReference vr[], size_t n, const fmi3Float64 value[],
                          size_t nValues) {
    Instance *c = (Instance *)comp;
    size_t i;
    if (!c) return fmi3Error;
    if (!count_ok(c, "fmi3SetFloat64", n, nValues)) return fmi3Error;
    for (i = 0; i < n; i++) {
        fmi3ValueReference r = vr[i];
        Snapshot *s = &c->s;
        int after_init = s->state >= ST_STEP;
        if (r == VR_STROKE) s->stroke = value[i];
        else if (r == VR_VELOCITY) s->velocity = value[i];
        else if (r == VR_TEMPERATURE && HAS_EFFECTS) s->temperature = value[i];
        else if (r == VR_MAX_STEP || r == VR_TOLERANCE || r == VR_STROKE_LIMIT || r == VR_VELOCITY_LIMIT) {
            if (after_init) return fail(c, "%s", "the integrator settings and input limits are fixed parameters: "
                                                "set them before fmi3ExitInitializationMode");
            if (r == VR_MAX_STEP) s->max_step = value[i];
            else if (r == VR_TOLERANCE) s->tolerance = value[i];
            else if (r == VR_STROKE_LIMIT) s->stroke_limit = value[i];
            else s->velocity_limit = value[i];
        } else if (is_param(r)) {
            int k = (int)(r - VR_PARAM);
            if (after_init && is_fixed_param(k))
                return fail(c, "%s is a fixed parameter: set it before fmi3ExitInitializationMode", SPECS[k].name);
            s->p[k] = value[i];
            s->dirty = 1;
        } else {
            char d[160];
            snprintf(d, sizeof d, "fmi3SetFloat64: unknown or read-only value reference %u", (unsigned)r);
            return fail(c, "%s", d);
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance comp, const fmi3ValueReference vr[], size_t n, fmi3Int32 value[],
                        size_t nValues) {
    Instance *c = (Instance *)comp;
    size_t i;
    if (!c) return fmi3Error;
    if (!count_ok(c, "fmi3GetInt32", n, nValues)) return fmi3Error;
    for (i = 0; i < n; i++) {
        if (vr[i] == VR_INPUT_INTERPOLATION) value[i] = c->s.input_interpolation;
        else if (vr[i] == VR_THERMAL_SOURCE && HAS_EFFECTS) value[i] = c->s.thermal_source;
        else return unknown_vr(c, "fmi3GetInt32", vr[i]);
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance comp, const fmi3ValueReference vr[], size_t n, const fmi3Int32 value[],
                        size_t nValues) {
    Instance *c = (Instance *)comp;
    size_t i;
    if (!c) return fmi3Error;
    if (!count_ok(c, "fmi3SetInt32", n, nValues)) return fmi3Error;
    for (i = 0; i < n; i++) {
        if (c->s.state >= ST_STEP)
            return fail(c, "%s", "input_interpolation and thermal_source are fixed: set them before "
                                 "fmi3ExitInitializationMode");
        if (vr[i] == VR_INPUT_INTERPOLATION) {
            if (value[i] != 0 && value[i] != 1) return fail(c, "%s", "input_interpolation must be 0 or 1");
            c->s.input_interpolation = value[i];
        } else if (vr[i] == VR_THERMAL_SOURCE && HAS_EFFECTS) {
            if (value[i] != 0 && value[i] != 1) return fail(c, "%s", "thermal_source must be 0 or 1");
            c->s.thermal_source = value[i];
        } else return unknown_vr(c, "fmi3SetInt32", vr[i]);
    }
    return fmi3OK;
}

/* The types this FMU has no variable of: an empty request is fine, any value reference an error. */
#define NO_VARIABLES(FN, T, CONST, TYPE) \
    fmi3Status FN(fmi3Instance c, const fmi3ValueReference vr[], size_t n, CONST T v[], size_t nv) { \
        (void)vr; (void)v; (void)nv; \
        if (!c) return fmi3Error; \
        return n ? fail((Instance *)c, "%s: this FMU has no " TYPE " variables (Float64 and Int32 only)", #FN) \
                 : fmi3OK; \
    }
NO_VARIABLES(fmi3GetFloat32, fmi3Float32, , "Float32")
NO_VARIABLES(fmi3GetInt8, fmi3Int8, , "Int8")
NO_VARIABLES(fmi3GetUInt8, fmi3UInt8, , "UInt8")
NO_VARIABLES(fmi3GetInt16, fmi3Int16, , "Int16")
NO_VARIABLES(fmi3GetUInt16, fmi3UInt16, , "UInt16")
NO_VARIABLES(fmi3GetUInt32, fmi3UInt32, , "UInt32")
NO_VARIABLES(fmi3GetInt64, fmi3Int64, , "Int64")
NO_VARIABLES(fmi3GetUInt64, fmi3UInt64, , "UInt64")
NO_VARIABLES(fmi3GetBoolean, fmi3Boolean, , "Boolean")
NO_VARIABLES(fmi3GetString, fmi3String, , "String")
NO_VARIABLES(fmi3SetFloat32, fmi3Float32, const, "Float32")
NO_VARIABLES(fmi3SetInt8, fmi3Int8, const, "Int8")
NO_VARIABLES(fmi3SetUInt8, fmi3UInt8, const, "UInt8")
NO_VARIABLES(fmi3SetInt16, fmi3Int16, const, "Int16")
NO_VARIABLES(fmi3SetUInt16, fmi3UInt16, const, "UInt16")
NO_VARIABLES(fmi3SetUInt32, fmi3UInt32, const, "UInt32")
NO_VARIABLES(fmi3SetInt64, fmi3Int64, const, "Int64")
NO_VARIABLES(fmi3SetUInt64, fmi3UInt64, const, "UInt64")
NO_VARIABLES(fmi3SetBoolean, fmi3Boolean, const, "Boolean")
NO_VARIABLES(fmi3SetString, fmi3String, const, "String")

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, size_t sizes[], fmi3Binary v[],
                         size_t nv) {
    (void)vr; (void)sizes; (void)v; (void)nv;
    if (!c) return fmi3Error;
    return n ? fail((Instance *)c, "%s", "fmi3GetBinary: this FMU has no Binary variables") : fmi3OK;
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const size_t sizes[],
                         const fmi3Binary v[], size_t nv) {
    (void)vr; (void)sizes; (void)v; (void)nv;
    if (!c) return fmi3Error;
    return n ? fail((Instance *)c, "%s", "fmi3SetBinary: this FMU has no Binary variables") : fmi3OK;
}

/* ---- clocks: none ------------------------------------------------------------------------------ */

static fmi3Status no_clocks(fmi3Instance c, const char *fn) {
    return fail((Instance *)c, "%s: this FMU has no clocks", fn);
}
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Clock v[]) {
    (void)vr; (void)n; (void)v;
    return no_clocks(c, "fmi3GetClock");
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Clock v[]) {
    (void)vr; (void)n; (void)v;
    return no_clocks(c, "fmi3SetClock");
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 iv[],
                                  fmi3IntervalQualifier q[]) {
    (void)vr; (void)n; (void)iv; (void)q;
    return no_clocks(c, "fmi3GetIntervalDecimal");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 cnt[],
                                   fmi3UInt64 res[], fmi3IntervalQualifier q[]) {
    (void)vr; (void)n; (void)cnt; (void)res; (void)q;
    return no_clocks(c, "fmi3GetIntervalFraction");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 sh[]) {
    (void)vr; (void)n; (void)sh;
    return no_clocks(c, "fmi3GetShiftDecimal");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 cnt[],
                                fmi3UInt64 res[]) {
    (void)vr; (void)n; (void)cnt; (void)res;
    return no_clocks(c, "fmi3GetShiftFraction");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 iv[]) {
    (void)vr; (void)n; (void)iv;
    return no_clocks(c, "fmi3SetIntervalDecimal");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 cnt[],
                                   const fmi3UInt64 res[]) {
    (void)vr; (void)n; (void)cnt; (void)res;
    return no_clocks(c, "fmi3SetIntervalFraction");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 sh[]) {
    (void)vr; (void)n; (void)sh;
    return no_clocks(c, "fmi3SetShiftDecimal");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 cnt[],
                                const fmi3UInt64 res[]) {
    (void)vr; (void)n; (void)cnt; (void)res;
    return no_clocks(c, "fmi3SetShiftFraction");
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock, fmi3Float64 t) {
    (void)clock; (void)t;
    return fail((Instance *)c, "%s", "fmi3ActivateModelPartition: co-simulation only (no scheduled execution)");
}

/* ---- dependencies, derivatives, configuration ---------------------------------------------- */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n) {
    (void)vr; (void)n;
    return fail((Instance *)c, "%s", "fmi3GetNumberOfVariableDependencies: not provided "
                                     "(providesPerElementDependencies=\"false\"; see ModelStructure)");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dep, size_t ed[], fmi3ValueReference ind[],
                                       size_t ei[], fmi3DependencyKind k[], size_t n) {
    (void)dep; (void)ed; (void)ind; (void)ei; (void)k; (void)n;
    return fail((Instance *)c, "%s", "fmi3GetVariableDependencies: not provided "
                                     "(providesPerElementDependencies=\"false\"; see ModelStructure)");
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                        const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
                                        size_t ns, fmi3Float64 sens[], size_t nsens) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return fail((Instance *)c, "%s", "directional derivatives are not provided (providesDirectionalDerivatives="
                                     "\"false\")");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[], size_t ns,
                                    fmi3Float64 sens[], size_t nsens) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return fail((Instance *)c, "%s", "adjoint derivatives are not provided (providesAdjointDerivatives=\"false\")");
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return fail((Instance *)c, "%s", "fmi3EnterConfigurationMode: this FMU has no structural parameters");
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return fail((Instance *)c, "%s", "fmi3ExitConfigurationMode: this FMU has no structural parameters");
}

/* ---- FMU state ----------------------------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance comp, fmi3FMUState *state) {
    Instance *c = (Instance *)comp;
    Snapshot *snap;
    if (!c || !state) return fmi3Error;
    snap = (Snapshot *)*state;
    if (!snap) {
        snap = (Snapshot *)calloc(1, sizeof *snap);
        if (!snap) return fail(c, "%s", "out of memory for the FMU state");
    }
    {
        DkSim keep = snap->sim;
        *snap = c->s;
        snap->sim = keep;
        if (dk_sim_copy(&snap->sim, &c->s.sim)) return fail(c, "%s", "out of memory for the FMU state");
    }
    *state = snap;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance comp, fmi3FMUState state) {
    Instance *c = (Instance *)comp;
    Snapshot *snap = (Snapshot *)state;
    if (!c) return fmi3Error;
    if (!snap) return fail(c, "%s", "fmi3SetFMUState: no FMU state given");
    {
        DkSim keep = c->s.sim;
        c->s = *snap;
        c->s.sim = keep;
        if (dk_sim_copy(&c->s.sim, &snap->sim)) return fail(c, "%s", "out of memory restoring the FMU state");
    }
    return fmi3OK;
}

/* The fmi3 functions never call one another (a host that loads several FMUs with RTLD_GLOBAL may
   resolve an exported name to another FMU's). */
static void free_snapshot(fmi3FMUState *state) {
    if (state && *state) {
        Snapshot *snap = (Snapshot *)*state;
        dk_sim_free(&snap->sim);
        free(snap);
        *state = NULL;
    }
}

fmi3Status fmi3FreeFMUState(fmi3Instance comp, fmi3FMUState *state) {
    (void)comp;
    free_snapshot(state);
    return fmi3OK;
}

#define MAGIC 0x44616d33 /* "Dam3": an FMI 2.0 FMU's serialized state is refused */

static size_t serialized_size(const Snapshot *snap) {
    return 2 * sizeof(int) + sizeof(Snapshot) + 2 * (size_t)snap->sim.e.hist_len * sizeof(double);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance comp, fmi3FMUState state, size_t *size) {
    Snapshot *snap = (Snapshot *)state;
    if (!comp) return fmi3Error;
    if (!snap || !size) return fail((Instance *)comp, "%s", "fmi3SerializedFMUStateSize: no FMU state given");
    *size = serialized_size(snap);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance comp, fmi3FMUState state, fmi3Byte buf[], size_t size) {
    Snapshot *snap = (Snapshot *)state;
    int head[2] = {MAGIC, (int)sizeof(Snapshot)}, i;
    fmi3Byte *p = buf;
    if (!comp) return fmi3Error;
    if (!snap) return fail((Instance *)comp, "%s", "fmi3SerializeFMUState: no FMU state given");
    if (size < serialized_size(snap)) return fail((Instance *)comp, "%s", "fmi3SerializeFMUState: buffer too small");
    memcpy(p, head, sizeof head); p += sizeof head;
    memcpy(p, snap, sizeof *snap); p += sizeof *snap;
    for (i = 0; i < snap->sim.e.hist_len; i++) {
        const double *q = snap->sim.e.hist + 2 * ((snap->sim.e.hist_head + i) % snap->sim.e.hist_cap);
        memcpy(p, q, 2 * sizeof(double)); p += 2 * sizeof(double);
    }
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance comp, const fmi3Byte buf[], size_t size, fmi3FMUState *state) {
    Instance *c = (Instance *)comp;
    int head[2];
    Snapshot *snap;
    size_t nh;
    if (!c || !state) return fmi3Error;
    if (size < sizeof head + sizeof(Snapshot)) return fail(c, "%s", "serialized FMU state too short");
    memcpy(head, buf, sizeof head);
    if (head[0] != MAGIC || head[1] != (int)sizeof(Snapshot))
        return fail(c, "%s", "serialized FMU state is not from this FMU build");
    if (*state) free_snapshot(state);
    snap = (Snapshot *)calloc(1, sizeof *snap);
    if (!snap) return fail(c, "%s", "out of memory for the FMU state");
    memcpy(snap, buf + sizeof head, sizeof *snap);
    nh = (size_t)snap->sim.e.hist_len;
    if (size < sizeof head + sizeof(Snapshot) + 2 * nh * sizeof(double)) {
        free(snap);
        return fail(c, "%s", "serialized FMU state truncated");
    }
    snap->sim.e.hist = NULL; snap->sim.e.hist_cap = 0; snap->sim.e.hist_head = 0;
    if (nh) {
        snap->sim.e.hist = (double *)malloc(2 * nh * sizeof(double));
        if (!snap->sim.e.hist) { free(snap); return fail(c, "%s", "out of memory for the FMU state"); }
        memcpy(snap->sim.e.hist, buf + sizeof head + sizeof(Snapshot), 2 * nh * sizeof(double));
        snap->sim.e.hist_cap = (int)nh;
    }
    *state = snap;
    return fmi3OK;
}

/* ---- co-simulation ------------------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    return fail((Instance *)c, "%s", "fmi3EnterStepMode: this FMU has no event mode (hasEventMode=\"false\"); "
                                     "fmi3ExitInitializationMode enters step mode");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int32 order[],
                                    fmi3Float64 v[], size_t nv) {
    (void)vr; (void)order; (void)v; (void)nv;
    if (!c) return fmi3Error;
    return n ? fail((Instance *)c, "%s", "output derivatives are not provided (maxOutputDerivativeOrder=0)")
             : fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance comp, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    Instance *c = (Instance *)comp;
    Snapshot *s;
    char d[600];
    (void)noSetPrior;
    if (!c) return fmi3Error;
    s = &c->s;
    /* never an event, never a request to stop, never an early return */
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = s->time;
    if (s->state != ST_STEP) {
        return fail(c, "%s", s->state == ST_ERROR ? "the FMU is in an error state (see the earlier message); "
                                                    "reset or re-instantiate it"
                                                  : "fmi3DoStep before fmi3ExitInitializationMode");
    }
    if (!(h > 0.0)) {
        snprintf(d, sizeof d, "%g", h);
        return fail(c, "communication step size must be positive, got %s s", d);
    }
    if ((s->dirty && build(c)) || check_inputs(c)) { s->state = ST_ERROR; return fmi3Error; }
    s->sim.has_temperature = HAS_EFFECTS && s->thermal_source;
    s->sim.temperature_input = s->temperature;
    if (dk_sim_step(&s->sim, h, s->stroke, s->velocity, NULL)) {
        snprintf(d, sizeof d, "step at t = %.9g s failed: %s", t, s->sim.msg);
        return fail_state(c, "%s", d);
    }
    s->time = t + h;
    if (lastSuccessfulTime) *lastSuccessfulTime = s->time;
    return fmi3OK;
}

/* ---- event mode and model exchange: not supported (co-simulation without event mode) ---------- */

static fmi3Status cs_only(fmi3Instance c, const char *fn) {
    return fail((Instance *)c, "%s: co-simulation without event mode only", fn);
}
fmi3Status fmi3EnterEventMode(fmi3Instance c) { return cs_only(c, "fmi3EnterEventMode"); }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { return cs_only(c, "fmi3EvaluateDiscreteStates"); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *a, fmi3Boolean *b, fmi3Boolean *d, fmi3Boolean *e,
                                    fmi3Boolean *f, fmi3Float64 *g) {
    (void)a; (void)b; (void)d; (void)e; (void)f; (void)g;
    return cs_only(c, "fmi3UpdateDiscreteStates");
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { return cs_only(c, "fmi3EnterContinuousTimeMode"); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean a, fmi3Boolean *b, fmi3Boolean *d) {
    (void)a; (void)b; (void)d;
    return cs_only(c, "fmi3CompletedIntegratorStep");
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) {
    (void)t;
    return cs_only(c, "fmi3SetTime");
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    return cs_only(c, "fmi3SetContinuousStates");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 d[], size_t n) {
    (void)d; (void)n;
    return cs_only(c, "fmi3GetContinuousStateDerivatives");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 e[], size_t n) {
    (void)e; (void)n;
    return cs_only(c, "fmi3GetEventIndicators");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    return cs_only(c, "fmi3GetContinuousStates");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    return cs_only(c, "fmi3GetNominalsOfContinuousStates");
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)n;
    return cs_only(c, "fmi3GetNumberOfEventIndicators");
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)n;
    return cs_only(c, "fmi3GetNumberOfContinuousStates");
}
