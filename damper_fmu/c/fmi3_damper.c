/* FMI 3.0 co-simulation interface of the damper models (native FMU).
 *
 * The FMI 3.0 twin of fmi2_damper.c: the same FMI-independent part (fmu_common.c, with the kernel
 * damper_kernel.c, included here; compile this file and damper_fmu_values.c, this FMU's generated
 * instantiation token and start values) and the same generated headers: damper_fmu_config.h (model
 * kind) and damper_params.h (the parameters, from damper_fmu/parameters.py). Same life cycle,
 * same checks, same messages, same calls into the kernel in the same order, so the forces equal the
 * FMI 2.0 FMU's bit for bit (tests/test_fmi3.py). What FMI 3.0 changes:
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
/* FMI3_FUNCTION_PREFIX (source-code import of several FMUs into one program) is honoured by the
   standard header; everything else in this translation unit is static, the kernel included. */
#include "fmi3Functions.h"

#define FMI "fmi3"
#define STATE_MAGIC 0x44616d33 /* "Dam3": an FMI 2.0 FMU's serialized state is refused */
#define VR_TIME 4
#define VR_INPUT_INTERPOLATION 60 /* Int32 */
#define VR_THERMAL_SOURCE 61      /* Int32 */
typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Callbacks;

/* the FMI-independent part: the kernel, the instance and its state, checks, steps (shared with FMI 2.0) */
#include "fmu_common.c"

/* The message is prefixed with the instance name (FMI 3.0's logger has no instance argument). */
static void logmsg(Instance *c, fmi3Status status, const char *category, const char *fmt, ...) {
    char buf[1024];
    int n;
    va_list ap;
    if (!c || !c->cb.log) return;
    if (status == fmi3OK && !c->logging) return;
    n = snprintf(buf, sizeof buf, "%s: ", c->name);
    if (n < 0 || (size_t)n >= sizeof buf) n = 0;
    va_start(ap, fmt);
    vsnprintf(buf + n, sizeof buf - (size_t)n, fmt, ap);
    va_end(ap);
    c->cb.log(c->cb.env, status, category, buf);
}

static void error_message(Instance *c, const char *fmt, const char *detail) {
    logmsg(c, fmi3Error, "logStatusError", fmt, detail);
}

static fmi3Status fail(Instance *c, const char *fmt, const char *detail) {
    error_message(c, fmt, detail);
    return fmi3Error;
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
    Callbacks cb;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)required; (void)nRequired;
    (void)intermediateUpdate; /* providesIntermediateUpdate="false": never called */
    if (eventModeUsed) {
        if (logMessage)
            logMessage(env, fmi3Error, "logStatusError",
                       "eventModeUsed = true, but this FMU has no event mode (hasEventMode=\"false\")");
        return NULL;
    }
    if (!token || strcmp(token, DK_GUID) != 0) {
        if (logMessage) {
            char msg[256];
            snprintf(msg, sizeof msg, "instantiation token does not match this binary's %s (modelDescription.xml "
                     "and binary from different builds)", DK_GUID);
            logMessage(env, fmi3Error, "logStatusError", msg);
        }
        return NULL;
    }
    cb.env = env;
    cb.log = logMessage;
    return instance_new(name, &cb, logging);
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

void fmi3FreeInstance(fmi3Instance comp) { instance_free((Instance *)comp); }

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

fmi3Status fmi3ExitInitializationMode(fmi3Instance comp) {
    Instance *c = (Instance *)comp;
    if (!c) return fmi3Error;
    return exit_initialization(c) ? fmi3Error : fmi3OK;
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
    instance_reset(c);
    return fmi3OK;
}

/* ---- variables ----------------------------------------------------------------------------- */

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
        if (is_output(r) && !have_diag) {
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
        if (r == VR_TIME) value[i] = s->time;
        else if (get_float(c, r, force0, diag, &value[i])) return unknown_vr(c, "fmi3GetFloat64", r);
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance comp, const fmi3ValueReference vr[], size_t n, const fmi3Float64 value[],
                          size_t nValues) {
    Instance *c = (Instance *)comp;
    size_t i;
    if (!c) return fmi3Error;
    if (!count_ok(c, "fmi3SetFloat64", n, nValues)) return fmi3Error;
    for (i = 0; i < n; i++) {
        int st = set_float(c, vr[i], value[i]);
        if (st == 1) return fmi3Error;
        if (st == 2) {
            char d[160];
            snprintf(d, sizeof d, "fmi3SetFloat64: unknown or read-only value reference %u", (unsigned)vr[i]);
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
        int v;
        if (get_integer(c, vr[i], &v)) return unknown_vr(c, "fmi3GetInt32", vr[i]);
        value[i] = v;
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
        int st = set_integer(c, vr[i], value[i]);
        if (st == 1) return fmi3Error;
        if (st == 2) return unknown_vr(c, "fmi3SetInt32", vr[i]);
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
    if (!c || !state) return fmi3Error;
    return state_get(c, state) ? fmi3Error : fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance comp, fmi3FMUState state) {
    Instance *c = (Instance *)comp;
    if (!c) return fmi3Error;
    if (!state) return fail(c, "%s", "fmi3SetFMUState: no FMU state given");
    return state_set(c, (const Snapshot *)state) ? fmi3Error : fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance comp, fmi3FMUState *state) {
    (void)comp;
    state_free(state);
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance comp, fmi3FMUState state, size_t *size) {
    if (!comp) return fmi3Error;
    if (!state || !size) return fail((Instance *)comp, "%s", "fmi3SerializedFMUStateSize: no FMU state given");
    *size = serialized_size((const Snapshot *)state);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance comp, fmi3FMUState state, fmi3Byte buf[], size_t size) {
    if (!comp) return fmi3Error;
    return state_serialize((Instance *)comp, (const Snapshot *)state, buf, size, "fmi3SerializeFMUState")
               ? fmi3Error : fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance comp, const fmi3Byte buf[], size_t size, fmi3FMUState *state) {
    if (!comp || !state) return fmi3Error;
    return state_deserialize((Instance *)comp, buf, size, state) ? fmi3Error : fmi3OK;
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
    int st;
    (void)noSetPrior;
    if (!c) return fmi3Error;
    /* never an event, never a request to stop, never an early return */
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = c->s.time;
    st = do_step(c, t, h, NULL); /* no input derivatives in FMI 3.0: the acceleration is estimated */
    if (st == STEP_BAD_INPUT || st == STEP_FAILED) c->s.state = ST_ERROR;
    if (st != STEP_OK) return fmi3Error;
    if (lastSuccessfulTime) *lastSuccessfulTime = c->s.time;
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
