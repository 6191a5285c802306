/*
 * Typed3: every FMI 3.0 scalar type the master exchanges, as an FMI 3.0 Co-Simulation FMU in plain C.
 *
 * Built by tests/support/typed_build.py (which writes the modelDescription.xml with the value references
 * below) for tests/engine/test_fmi_types.py. For each of the 13 types T (Float64, Float32, Int8, UInt8,
 * Int16, UInt16, Int32, UInt32, Int64, UInt64, Boolean, String, Enumeration) there is an input
 * u_T (value reference 10 + j) and an output y_T (30 + j), j in that order. Outputs change only in
 * fmi3DoStep (no direct feedthrough). After n steps (n = 0 in initialization):
 *   echo = true:  y_T = the value of u_T when the last step started (at initialization: u_T now);
 *   echo = false: y_T = a sequence of n that reaches each type's extremes (see generate()):
 *                 big = true makes y_Int64/y_UInt64 reach INT64_MIN / UINT64_MAX (beyond 2^53).
 * Parameters: 1 echo, 2 big (Boolean), 3 label (String, y_String = "<label>|<n>"),
 * 4 start (Float64), 5 k8 (Int8), 6 first (Enumeration, y_Enumeration at n = 0).
 */

#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#ifndef INSTANTIATION_TOKEN
#error "compile with -DINSTANTIATION_TOKEN=\"...\" (tests/support/typed_build.py does)"
#endif

enum { T_F64, T_F32, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_I64, T_U64, T_BOOL, T_STR, T_ENUM, N_TYPES };
enum { VR_TIME, VR_ECHO, VR_BIG, VR_LABEL, VR_START, VR_K8, VR_FIRST, N_PARAMS };
#define VR_IN 10
#define VR_OUT 30
#define N_VARS (VR_OUT + N_TYPES)
typedef enum { INSTANTIATED, INITIALIZATION, STEP, TERMINATED } State;
typedef enum { NONE, PARAMETER, INPUT, OUTPUT, INDEPENDENT } Causality;

typedef struct {
    int type;
    Causality causality;
    double f;    /* Float64, Float32 */
    int64_t i;   /* Int8 .. Int64, Enumeration */
    uint64_t u;  /* UInt8 .. UInt64 */
    bool b;
    char *s;
} Var;

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    State state;
    double time;
    uint64_t n;
    Var v[N_VARS];
} Unit;

static const int64_t ITEMS[4] = {1, 2, 5, -3};

static void say(Unit *u, fmi3Status status, const char *fmt, ...) {
    char text[512];
    va_list ap;
    if (u == NULL || u->log == NULL) return;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    u->log(u->env, status, status == fmi3OK ? "logEvents" : "logStatusError", text);
}

static fmi3Status refuse(Unit *u, const char *function) {
    say(u, fmi3Error, "%s is not supported by this FMU", function);
    return fmi3Error;
}

static char *copy_string(const char *s) {
    char *out = malloc(strlen(s != NULL ? s : "") + 1);
    if (out != NULL) strcpy(out, s != NULL ? s : "");
    return out;
}

static int set_string(Var *x, const char *s) {
    char *text = copy_string(s);
    if (text == NULL) return 0;
    free(x->s);
    x->s = text;
    return 1;
}

static void generate(Unit *u) {
    const uint64_t n = u->n;
    const bool big = u->v[VR_BIG].b;
    Var *y = &u->v[VR_OUT];
    char text[600];
    y[T_F64].f = u->v[VR_START].f + 0.25 * (double)n;
    y[T_F32].f = (double)((float)u->v[VR_START].f * 0.5f + 0.1f * (float)n);
    y[T_I8].i = (int8_t)(uint8_t)((uint64_t)u->v[VR_K8].i + 37u * n);
    y[T_U8].u = (uint8_t)(200u + 37u * n);
    y[T_I16].i = (int16_t)(uint16_t)(35536u + 4099u * n);
    y[T_U16].u = (uint16_t)(65535u - 257u * n);
    y[T_I32].i = (int32_t)(INT32_MIN + 7919 * (int64_t)n);
    y[T_U32].u = (uint32_t)(UINT32_MAX - 13u * n);
    y[T_I64].i = big ? INT64_MIN + (int64_t)n : -INT64_C(1099511627776) * (int64_t)n - 1;
    y[T_U64].u = big ? UINT64_MAX - n : (UINT64_C(1) << 52) + 3u * n;
    y[T_BOOL].b = n % 3 == 0;
    snprintf(text, sizeof text, "%s|%llu", u->v[VR_LABEL].s, (unsigned long long)n);
    set_string(&y[T_STR], text);
    y[T_ENUM].i = n == 0 ? u->v[VR_FIRST].i : ITEMS[n % 4];
}

static void update(Unit *u) {
    int j;
    if (!u->v[VR_ECHO].b) {
        generate(u);
        return;
    }
    for (j = 0; j < N_TYPES; j++) {
        Var *y = &u->v[VR_OUT + j], *x = &u->v[VR_IN + j];
        y->f = x->f; y->i = x->i; y->u = x->u; y->b = x->b;
        set_string(y, x->s);
    }
}

static void declare(Unit *u, int vr, int type, Causality causality) {
    u->v[vr].type = type;
    u->v[vr].causality = causality;
    u->v[vr].s = copy_string("");
}

/* The variable of a value reference if it has this type (Int64 functions serve Enumerations too). */
static Var *find(Unit *u, fmi3ValueReference vr, int type, const char *function, bool set) {
    Var *x;
    if (vr >= N_VARS || u->v[vr].causality == NONE ||
        !(u->v[vr].type == type || (type == T_I64 && u->v[vr].type == T_ENUM))) {
        say(u, fmi3Error, "%s: no variable of this type with value reference %u", function, vr);
        return NULL;
    }
    x = &u->v[vr];
    if (set && !(x->causality == INPUT || (x->causality == PARAMETER && u->state != STEP))) {
        say(u, fmi3Error, "%s: value reference %u cannot be set now", function, vr);
        return NULL;
    }
    return x;
}

#define ACCESSORS(NAME, CTYPE, TCODE, FIELD, STORE)                                                            \
    fmi3Status fmi3Get##NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, CTYPE v[],           \
                             size_t m) {                                                                         \
        Unit *u = (Unit *)instance;                                                                              \
        size_t k;                                                                                                \
        if (m != n) return refuse(u, "fmi3Get" #NAME " with arrays");                                            \
        for (k = 0; k < n; k++) {                                                                                \
            Var *x = find(u, vr[k], TCODE, "fmi3Get" #NAME, false);                                              \
            if (x == NULL) return fmi3Error;                                                                     \
            v[k] = (CTYPE)x->FIELD;                                                                              \
        }                                                                                                        \
        return fmi3OK;                                                                                           \
    }                                                                                                            \
    fmi3Status fmi3Set##NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const CTYPE v[],     \
                             size_t m) {                                                                         \
        Unit *u = (Unit *)instance;                                                                              \
        size_t k;                                                                                                \
        if (m != n) return refuse(u, "fmi3Set" #NAME " with arrays");                                            \
        for (k = 0; k < n; k++) {                                                                                \
            Var *x = find(u, vr[k], TCODE, "fmi3Set" #NAME, true);                                               \
            if (x == NULL) return fmi3Error;                                                                     \
            STORE;                                                                                               \
        }                                                                                                        \
        if (u->state == INITIALIZATION) update(u);                                                               \
        return fmi3OK;                                                                                           \
    }

ACCESSORS(Float64, fmi3Float64, T_F64, f, x->f = v[k])
ACCESSORS(Float32, fmi3Float32, T_F32, f, x->f = (double)v[k])
ACCESSORS(Int8, fmi3Int8, T_I8, i, x->i = v[k])
ACCESSORS(UInt8, fmi3UInt8, T_U8, u, x->u = v[k])
ACCESSORS(Int16, fmi3Int16, T_I16, i, x->i = v[k])
ACCESSORS(UInt16, fmi3UInt16, T_U16, u, x->u = v[k])
ACCESSORS(Int32, fmi3Int32, T_I32, i, x->i = v[k])
ACCESSORS(UInt32, fmi3UInt32, T_U32, u, x->u = v[k])
ACCESSORS(Int64, fmi3Int64, T_I64, i, x->i = v[k])
ACCESSORS(UInt64, fmi3UInt64, T_U64, u, x->u = v[k])
ACCESSORS(Boolean, fmi3Boolean, T_BOOL, b, x->b = v[k])
ACCESSORS(String, fmi3String, T_STR, s, if (!set_string(x, v[k])) return fmi3Error)

/* ---- version, logging, instantiation -------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories;
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
    int j;
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        if (logMessage != NULL)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", "wrong instantiation token");
        return NULL;
    }
    u = calloc(1, sizeof *u);
    if (u == NULL) return NULL;
    u->env = instanceEnvironment;
    u->log = logMessage;
    declare(u, VR_TIME, T_F64, INDEPENDENT);
    declare(u, VR_ECHO, T_BOOL, PARAMETER);
    declare(u, VR_BIG, T_BOOL, PARAMETER);
    declare(u, VR_LABEL, T_STR, PARAMETER);
    declare(u, VR_START, T_F64, PARAMETER);
    declare(u, VR_K8, T_I8, PARAMETER);
    declare(u, VR_FIRST, T_ENUM, PARAMETER);
    set_string(&u->v[VR_LABEL], "typed");
    u->v[VR_FIRST].i = 1;
    for (j = 0; j < N_TYPES; j++) {
        declare(u, VR_IN + j, j, INPUT);
        declare(u, VR_OUT + j, j, OUTPUT);
    }
    u->v[VR_IN + T_ENUM].i = 1;
    u->state = INSTANTIATED;
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
    int k;
    if (u == NULL) return;
    for (k = 0; k < N_VARS; k++) free(u->v[k].s);
    free(u);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Unit *u = (Unit *)instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    u->time = u->v[VR_TIME].f = startTime;
    u->state = INITIALIZATION;
    update(u);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Unit *u = (Unit *)instance;
    update(u);
    u->state = STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return refuse(instance, "fmi3EnterEventMode"); }

fmi3Status fmi3Terminate(fmi3Instance instance) {
    ((Unit *)instance)->state = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) { return refuse(instance, "fmi3Reset"); }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    Unit *u = (Unit *)instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    if (u->state != STEP) return refuse(u, "fmi3DoStep outside step mode");
    u->time = u->v[VR_TIME].f = currentCommunicationPoint + communicationStepSize;
    *lastSuccessfulTime = u->time;
    u->n += 1;
    update(u);
    return fmi3OK;
}

/* ---- not supported by this FMU --------------------------------------------------------------- */

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

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, size_t sizes[],
                         fmi3Binary v[], size_t m) {
    UNUSED_ARRAYS(vr, n, v); (void)sizes; (void)m; return refuse(instance, "fmi3GetBinary");
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Clock v[]) {
    UNUSED_ARRAYS(vr, n, v); return refuse(instance, "fmi3GetClock");
}
#include "fmi3_refused.h" /* tests/support/fmi3/, on the include path */
