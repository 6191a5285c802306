/*
 * ConstantCurrent3: a constant-current source as an FMI 3.0 Co-Simulation FMU, in plain C.
 *
 * The FMI 3.0 counterpart of the pythonfmu ConstantCurrent unit, for the master's FMI 3.0
 * tests (built by tests/support/fmi3_build.py, which writes the modelDescription.xml):
 *
 *   i = enabled ? count * current + offset : 0        [A], output, direct feedthrough from offset
 *
 * Value references (must match tests/support/fmi3_build.py):
 *   0 time (independent)  1 current (Float64 parameter, A)  2 i (Float64 output, A)
 *   3 offset (Float64 input, A)  4 fail_at (Float64 parameter, s)  5 fail_mode (Int32 parameter)
 *   6 count (Int64 parameter)  7 enabled (Boolean parameter)  8 tag (String parameter)
 *
 * Failure injection for the master's tests: the first fmi3DoStep whose midpoint is past
 * fail_at (fail_at >= 0) fails as fail_mode says: 1 returns fmi3Error, 2 sets
 * terminateSimulation (status OK), 3 returns fmi3Fatal; 0 never fails.
 * With logging on, fmi3Terminate and fmi3FreeInstance log an OK message naming the call,
 * so tests can check which teardown calls the importer made.
 */

#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#ifndef INSTANTIATION_TOKEN
#error "compile with -DINSTANTIATION_TOKEN=\"...\" (tests/support/fmi3_build.py does)"
#endif

enum { VR_TIME, VR_CURRENT, VR_I, VR_OFFSET, VR_FAIL_AT, VR_FAIL_MODE, VR_COUNT, VR_ENABLED, VR_TAG };
enum { FAIL_NONE, FAIL_ERROR, FAIL_TERMINATE, FAIL_FATAL };
typedef enum { INSTANTIATED, INITIALIZATION, STEP, TERMINATED, FAILED } State;

typedef struct {
    char *name;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    bool logging;
    State state;
    double time;
    double current, offset, fail_at;
    fmi3Int32 fail_mode;
    fmi3Int64 count;
    bool enabled;
    char *tag;
} Unit;

static void say(Unit *u, fmi3Status status, const char *category, const char *fmt, ...) {
    char text[512];
    va_list ap;
    if (u == NULL || u->log == NULL || (status == fmi3OK && !u->logging)) return;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    u->log(u->env, status, category, text);
}

static char *copy_string(const char *s) {
    char *out = malloc(strlen(s) + 1);
    if (out != NULL) strcpy(out, s);
    return out;
}

static double output_i(const Unit *u) {
    return u->enabled ? (double)u->count * u->current + u->offset : 0.0;
}

static fmi3Status refuse(Unit *u, const char *function) {
    say(u, fmi3Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi3Error;
}

/* Parameters may change before fmi3ExitInitializationMode, the input at any time before termination. */
static fmi3Status settable(Unit *u, fmi3ValueReference vr, const char *function) {
    if (u->state == FAILED || u->state == TERMINATED) {
        say(u, fmi3Error, "logStatusError", "%s: the instance is terminated or failed", function);
        return fmi3Error;
    }
    if (vr != VR_OFFSET && u->state == STEP) {
        say(u, fmi3Error, "logStatusError", "%s: value reference %u is a fixed parameter", function, vr);
        return fmi3Error;
    }
    return fmi3OK;
}

static fmi3Status unknown_vr(Unit *u, const char *function, fmi3ValueReference vr) {
    say(u, fmi3Error, "logStatusError", "%s: no variable of this type with value reference %u", function, vr);
    return fmi3Error;
}

/* ---- inquire version, logging, instantiation ------------------------------------------------ */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)nCategories;
    (void)categories;
    ((Unit *)instance)->logging = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    if (logMessage != NULL) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Unit *u;
    (void)resourcePath; (void)visible; (void)eventModeUsed; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        if (logMessage != NULL)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", "wrong instantiation token");
        return NULL;
    }
    u = calloc(1, sizeof *u);
    if (u == NULL) return NULL;
    u->name = copy_string(instanceName != NULL ? instanceName : "");
    u->tag = copy_string("");
    u->env = instanceEnvironment;
    u->log = logMessage;
    u->logging = loggingOn;
    u->state = INSTANTIATED;
    u->current = 0.0;
    u->offset = 0.0;
    u->fail_at = -1.0;
    u->fail_mode = FAIL_ERROR;
    u->count = 1;
    u->enabled = true;
    return u;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage != NULL) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Unit *u = (Unit *)instance;
    if (u == NULL) return;
    say(u, fmi3OK, "logEvents", "fmi3FreeInstance");
    free(u->name);
    free(u->tag);
    free(u);
}

/* ---- initialization, termination ------------------------------------------------------------ */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Unit *u = (Unit *)instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (u->state != INSTANTIATED) {
        say(u, fmi3Error, "logStatusError", "fmi3EnterInitializationMode called twice");
        return fmi3Error;
    }
    u->time = startTime;
    u->state = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Unit *u = (Unit *)instance;
    if (u->state != INITIALIZATION) {
        say(u, fmi3Error, "logStatusError", "fmi3ExitInitializationMode outside initialization mode");
        return fmi3Error;
    }
    if (u->tag[0] != '\0') say(u, fmi3OK, "logEvents", "tag: %s", u->tag);
    u->state = STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return refuse(instance, "fmi3EnterEventMode"); }

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Unit *u = (Unit *)instance;
    say(u, fmi3OK, "logEvents", "fmi3Terminate");
    u->state = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) { return refuse(instance, "fmi3Reset"); }

/* ---- getters and setters -------------------------------------------------------------------- */

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    if (nValues != nValueReferences) return refuse(u, "fmi3GetFloat64 with arrays");
    for (k = 0; k < nValueReferences; k++) {
        switch (valueReferences[k]) {
        case VR_TIME: values[k] = u->time; break;
        case VR_CURRENT: values[k] = u->current; break;
        case VR_I: values[k] = output_i(u); break;
        case VR_OFFSET: values[k] = u->offset; break;
        case VR_FAIL_AT: values[k] = u->fail_at; break;
        default: return unknown_vr(u, "fmi3GetFloat64", valueReferences[k]);
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    if (nValues != nValueReferences) return refuse(u, "fmi3SetFloat64 with arrays");
    for (k = 0; k < nValueReferences; k++) {
        if (settable(u, valueReferences[k], "fmi3SetFloat64") != fmi3OK) return fmi3Error;
        switch (valueReferences[k]) {
        case VR_CURRENT: u->current = values[k]; break;
        case VR_OFFSET: u->offset = values[k]; break;
        case VR_FAIL_AT: u->fail_at = values[k]; break;
        default: return unknown_vr(u, "fmi3SetFloat64", valueReferences[k]);
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] != VR_FAIL_MODE) return unknown_vr(u, "fmi3GetInt32", valueReferences[k]);
        values[k] = u->fail_mode;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (settable(u, valueReferences[k], "fmi3SetInt32") != fmi3OK) return fmi3Error;
        if (valueReferences[k] != VR_FAIL_MODE) return unknown_vr(u, "fmi3SetInt32", valueReferences[k]);
        if (values[k] < FAIL_NONE || values[k] > FAIL_FATAL) {
            say(u, fmi3Error, "logStatusError", "fail_mode must be 0..3, got %d", (int)values[k]);
            return fmi3Error;
        }
        u->fail_mode = values[k];
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int64 values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] != VR_COUNT) return unknown_vr(u, "fmi3GetInt64", valueReferences[k]);
        values[k] = u->count;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int64 values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (settable(u, valueReferences[k], "fmi3SetInt64") != fmi3OK) return fmi3Error;
        if (valueReferences[k] != VR_COUNT) return unknown_vr(u, "fmi3SetInt64", valueReferences[k]);
        u->count = values[k];
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Boolean values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] != VR_ENABLED) return unknown_vr(u, "fmi3GetBoolean", valueReferences[k]);
        values[k] = u->enabled;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Boolean values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (settable(u, valueReferences[k], "fmi3SetBoolean") != fmi3OK) return fmi3Error;
        if (valueReferences[k] != VR_ENABLED) return unknown_vr(u, "fmi3SetBoolean", valueReferences[k]);
        u->enabled = values[k];
    }
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         fmi3String values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] != VR_TAG) return unknown_vr(u, "fmi3GetString", valueReferences[k]);
        values[k] = u->tag;
    }
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const fmi3String values[], size_t nValues) {
    Unit *u = (Unit *)instance;
    size_t k;
    char *text;
    (void)nValues;
    for (k = 0; k < nValueReferences; k++) {
        if (settable(u, valueReferences[k], "fmi3SetString") != fmi3OK) return fmi3Error;
        if (valueReferences[k] != VR_TAG) return unknown_vr(u, "fmi3SetString", valueReferences[k]);
        text = copy_string(values[k] != NULL ? values[k] : "");
        if (text == NULL) return fmi3Error;
        free(u->tag);
        u->tag = text;
    }
    return fmi3OK;
}

/* ---- stepping ------------------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    Unit *u = (Unit *)instance;
    const double t = currentCommunicationPoint, h = communicationStepSize;
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    *lastSuccessfulTime = t;
    if (u->state != STEP) {
        say(u, fmi3Error, "logStatusError", "fmi3DoStep outside step mode");
        return fmi3Error;
    }
    if (!(h > 0.0)) {
        say(u, fmi3Error, "logStatusError", "fmi3DoStep: step size %g s is not positive", h);
        return fmi3Error;
    }
    if (u->fail_at >= 0.0 && u->fail_mode != FAIL_NONE && t + 0.5 * h > u->fail_at) {
        switch (u->fail_mode) {
        case FAIL_ERROR:
            u->state = FAILED;
            say(u, fmi3Error, "logStatusError", "injected error at t = %g s (fail_at = %g s)", t, u->fail_at);
            return fmi3Error;
        case FAIL_TERMINATE:
            say(u, fmi3Warning, "logStatusWarning", "requesting the end of the simulation at t = %g s", t + h);
            u->time = t + h;
            *lastSuccessfulTime = t + h;
            *terminateSimulation = true;
            return fmi3Warning;
        default:
            u->state = FAILED;
            say(u, fmi3Fatal, "logStatusFatal", "injected fatal error at t = %g s", t);
            return fmi3Fatal;
        }
    }
    u->time = t + h;
    *lastSuccessfulTime = u->time;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)instance;
    *nContinuousStates = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)instance;
    *nEventIndicators = 0;
    return fmi3OK;
}

/* ---- everything else is refused (every FMI 3.0 function must be exported) --------------------- */

#define UNUSED_ARRAYS(a, b, c) (void)(a); (void)(b); (void)(c)

fmi3Status fmi3GetFloat32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float32 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetFloat32");
}
fmi3Status fmi3GetInt8(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Int8 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetInt8");
}
fmi3Status fmi3GetUInt8(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt8 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetUInt8");
}
fmi3Status fmi3GetInt16(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Int16 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetInt16");
}
fmi3Status fmi3GetUInt16(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt16 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetUInt16");
}
fmi3Status fmi3GetUInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt32 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetUInt32");
}
fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt64 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3GetUInt64");
}
fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, size_t sizes[],
                         fmi3Binary v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)sizes; (void)m; return refuse(instance, "fmi3GetBinary");
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Clock v[]) {
    UNUSED_ARRAYS(vr, n, v); return refuse(instance, "fmi3GetClock");
}
fmi3Status fmi3SetFloat32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Float32 v[],
                          size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetFloat32");
}
fmi3Status fmi3SetInt8(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Int8 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetInt8");
}
fmi3Status fmi3SetUInt8(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3UInt8 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetUInt8");
}
fmi3Status fmi3SetInt16(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Int16 v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetInt16");
}
fmi3Status fmi3SetUInt16(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3UInt16 v[],
                         size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetUInt16");
}
fmi3Status fmi3SetUInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3UInt32 v[],
                         size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetUInt32");
}
fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 v[],
                         size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)m; return refuse(instance, "fmi3SetUInt64");
}
#include "fmi3_refused.h"
