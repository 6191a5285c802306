/*
 * fmi2_frame.h: a small FMI 2.0 frame (Model Exchange, and Co-Simulation when CO_SIMULATION
 * is defined) for the master's Model Exchange tests; built by tests/support/me_build.py.
 *
 * A model file includes fmi2Functions.h, defines its sizes and state tables, includes this
 * header, then defines the hooks:
 *
 *   N_REAL, N_INT, N_STATES, N_INDICATORS       sizes (N_INT and N_INDICATORS may be 0)
 *   STATE_VR[N_STATES], DERIVATIVE_VR[N_STATES]  value references of states and derivatives in r[]
 *   model_defaults(m)        start values of r[] and i[]
 *   model_initialize(m)      at fmi2ExitInitializationMode: states from parameters
 *   model_derivatives(m)     derivatives and continuous outputs from r[] (states, inputs, parameters)
 *   model_indicators(m, z)   event indicators
 *   model_event(m)           discrete update at an event: sets values_changed, next_event_*, terminate
 *   model_check(m)           NULL, or why the derivatives cannot be evaluated now (returns fmi2Error)
 *
 * All Real variables live in r[] at index = value reference, Integer variables in i[].
 * The Co-Simulation fmi2DoStep integrates with classic Runge-Kutta (4th order), CS_SUBSTEPS
 * sub-steps per communication step, events at sub-step ends. Not supported (fmi2Error with a
 * message): FMU state, directional derivatives, input derivatives, Boolean and String variables.
 */

#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef MODEL_GUID
#error "compile with -DMODEL_GUID=\"{...}\" (tests/support/me_build.py does)"
#endif
#ifndef CS_SUBSTEPS
#define CS_SUBSTEPS 10
#endif

typedef enum { INSTANTIATED, INITIALIZATION, EVENT_MODE, CONTINUOUS_MODE, STEP_MODE, TERMINATED, FAILED } Mode;

typedef struct {
    char *name;
    fmi2CallbackFunctions cb;
    bool logging;
    fmi2Type type;
    Mode mode;
    double time;
    double r[N_REAL];
    fmi2Integer i[N_INT + 1];
    bool values_changed, next_event_defined, terminate;
    double next_event_time;
} Instance;

static void model_defaults(Instance *m);
static void model_initialize(Instance *m);
static void model_derivatives(Instance *m);
static void model_indicators(Instance *m, double *z);
static void model_event(Instance *m);
static const char *model_check(Instance *m);

static void say(Instance *m, fmi2Status status, const char *category, const char *fmt, ...) {
    char text[512];
    va_list ap;
    if (m == NULL || m->cb.logger == NULL || (status == fmi2OK && !m->logging)) return;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    m->cb.logger(m->cb.componentEnvironment, m->name, status, category, "%s", text);
}

static fmi2Status unsupported(fmi2Component c, const char *function) {
    say((Instance *)c, fmi2Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi2Error;
}

/* True when the time event is due at the instance's time (relative tolerance as Python's math.isclose). */
static bool time_event_due(const Instance *m) {
    return m->next_event_defined && m->time >= m->next_event_time - 1e-9 * fmax(1.0, fabs(m->next_event_time));
}

/* ---- common functions ---------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]) {
    (void)n; (void)categories;
    ((Instance *)c)->logging = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging) {
    Instance *m;
    (void)resources; (void)visible;
    if (functions == NULL || functions->logger == NULL) return NULL;
#ifndef CO_SIMULATION
    if (type != fmi2ModelExchange) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "this FMU supports Model Exchange only");
        return NULL;
    }
#endif
    if (guid == NULL || strcmp(guid, MODEL_GUID) != 0) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "wrong GUID %s, expected %s", guid ? guid : "(null)", MODEL_GUID);
        return NULL;
    }
    m = calloc(1, sizeof *m);
    if (m == NULL) return NULL;
    m->name = malloc(strlen(name) + 1);
    if (m->name == NULL) { free(m); return NULL; }
    strcpy(m->name, name);
    m->cb = *functions;
    m->logging = logging;
    m->type = type;
    m->mode = INSTANTIATED;
    model_defaults(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *m = c;
    if (m == NULL) return;
    free(m->name);
    free(m);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolerance_defined, fmi2Real tolerance,
                               fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tolerance_defined; (void)tolerance; (void)stop_defined; (void)stop;
    ((Instance *)c)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ((Instance *)c)->mode = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = c;
    model_initialize(m);
    model_derivatives(m);
    m->mode = m->type == fmi2ModelExchange ? EVENT_MODE : STEP_MODE;
    if (m->type == fmi2CoSimulation) {  /* the initial event iteration, done by the importer in ME */
        m->values_changed = false;
        model_event(m);
        model_derivatives(m);
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ((Instance *)c)->mode = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *m = c;
    m->mode = INSTANTIATED;
    m->next_event_defined = m->terminate = false;
    model_defaults(m);
    return fmi2OK;
}

static fmi2Status check_refs(Instance *m, const fmi2ValueReference vr[], size_t n, size_t size, const char *f) {
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= size) {
            say(m, fmi2Error, "logStatusError", "%s: unknown value reference %u", f, (unsigned)vr[k]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *m = c;
    if (check_refs(m, vr, n, N_REAL, "fmi2GetReal") != fmi2OK) return fmi2Error;
    if (m->mode == INITIALIZATION) model_initialize(m);  /* states are calculated from the parameters */
    if (m->mode != INSTANTIATED) model_derivatives(m);
    for (size_t k = 0; k < n; k++) value[k] = m->r[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    Instance *m = c;
    if (check_refs(m, vr, n, N_INT, "fmi2GetInteger") != fmi2OK) return fmi2Error;
    for (size_t k = 0; k < n; k++) value[k] = m->i[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2GetBoolean");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2GetString");
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *m = c;
    if (check_refs(m, vr, n, N_REAL, "fmi2SetReal") != fmi2OK) return fmi2Error;
    for (size_t k = 0; k < n; k++) m->r[vr[k]] = value[k];
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    Instance *m = c;
    if (check_refs(m, vr, n, N_INT, "fmi2SetInteger") != fmi2OK) return fmi2Error;
    for (size_t k = 0; k < n; k++) m->i[vr[k]] = value[k];
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetBoolean");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetString");
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2GetFMUstate"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return unsupported(c, "fmi2SetFMUstate"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2FreeFMUstate"); }

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)s; (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte bytes[], size_t size) {
    (void)s; (void)bytes; (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *s) {
    (void)s; (void)bytes; (void)size;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[], size_t nu,
                                        const fmi2ValueReference known[], size_t nk, const fmi2Real dv_known[],
                                        fmi2Real dv_unknown[]) {
    (void)unknown; (void)nu; (void)known; (void)nk; (void)dv_known; (void)dv_unknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

/* ---- Model Exchange ------------------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    ((Instance *)c)->mode = EVENT_MODE;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *m = c;
    m->values_changed = false;
    model_derivatives(m);
    model_event(m);
    model_derivatives(m);
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = m->terminate;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = m->values_changed;
    info->nextEventTimeDefined = m->next_event_defined;
    info->nextEventTime = m->next_event_time;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    ((Instance *)c)->mode = CONTINUOUS_MODE;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_set_prior, fmi2Boolean *enter_event_mode,
                                       fmi2Boolean *terminate) {
    (void)c; (void)no_set_prior;
    *enter_event_mode = fmi2False;
    *terminate = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    ((Instance *)c)->time = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *m = c;
    if (nx != N_STATES) {
        say(m, fmi2Error, "logStatusError", "fmi2SetContinuousStates: %u states, expected %u", (unsigned)nx,
            (unsigned)N_STATES);
        return fmi2Error;
    }
    for (size_t k = 0; k < nx; k++) m->r[STATE_VR[k]] = x[k];
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Instance *m = c;
    const char *why = model_check(m);
    if (why != NULL) {
        say(m, fmi2Error, "logStatusError", "%s", why);
        return fmi2Error;
    }
    model_derivatives(m);
    for (size_t k = 0; k < nx && k < N_STATES; k++) dx[k] = m->r[DERIVATIVE_VR[k]];
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    Instance *m = c;
    double all[N_INDICATORS + 1];
    model_derivatives(m);
    model_indicators(m, all);
    for (int k = 0; k < N_INDICATORS && (size_t)k < nz; k++) z[k] = all[k];
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Instance *m = c;
    for (size_t k = 0; k < nx && k < N_STATES; k++) x[k] = m->r[STATE_VR[k]];
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    (void)c;
    for (size_t k = 0; k < nx; k++) x_nominal[k] = 1.0;
    return fmi2OK;
}

/* ---- Co-Simulation -------------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

#if N_STATES > 0
static void rk4_substep(Instance *m, double dt) {
    double x0[N_STATES], k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES];
    const double t0 = m->time;
    int j;
    for (j = 0; j < N_STATES; j++) x0[j] = m->r[STATE_VR[j]];
    model_derivatives(m);
    for (j = 0; j < N_STATES; j++) { k1[j] = m->r[DERIVATIVE_VR[j]]; m->r[STATE_VR[j]] = x0[j] + 0.5 * dt * k1[j]; }
    m->time = t0 + 0.5 * dt;
    model_derivatives(m);
    for (j = 0; j < N_STATES; j++) { k2[j] = m->r[DERIVATIVE_VR[j]]; m->r[STATE_VR[j]] = x0[j] + 0.5 * dt * k2[j]; }
    model_derivatives(m);
    for (j = 0; j < N_STATES; j++) { k3[j] = m->r[DERIVATIVE_VR[j]]; m->r[STATE_VR[j]] = x0[j] + dt * k3[j]; }
    m->time = t0 + dt;
    model_derivatives(m);
    for (j = 0; j < N_STATES; j++) {
        k4[j] = m->r[DERIVATIVE_VR[j]];
        m->r[STATE_VR[j]] = x0[j] + dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    }
}
#endif

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior) {
    Instance *m = c;
    double z_before[N_INDICATORS + 1], z_after[N_INDICATORS + 1];
    const double end = t + h;
    (void)no_set_prior;
    if (m->type != fmi2CoSimulation) return unsupported(c, "fmi2DoStep (instantiated for Model Exchange)");
    m->time = t;
    for (int s = 1; s <= CS_SUBSTEPS; s++) {
        double target = t + h * s / CS_SUBSTEPS;
        const char *why = model_check(m);
        if (why != NULL) {
            say(m, fmi2Error, "logStatusError", "%s", why);
            m->mode = FAILED;
            return fmi2Error;
        }
        if (s == CS_SUBSTEPS) target = end;
        if (m->next_event_defined && m->next_event_time > m->time && m->next_event_time < target) {
            target = m->next_event_time;
            s--;  /* the same sub-step end again after the event */
        }
        model_indicators(m, z_before);
#if N_STATES > 0
        rk4_substep(m, target - m->time);
#endif
        m->time = target;
        model_derivatives(m);
        model_indicators(m, z_after);
        bool event = time_event_due(m);
        for (int k = 0; k < N_INDICATORS; k++) event = event || ((z_before[k] > 0) != (z_after[k] > 0));
        if (event) {
            model_event(m);
            model_derivatives(m);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetBooleanStatus");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}
