/*
 * Typed2: every FMI 2.0 type (Real, Integer, Boolean, String, Enumeration) as an FMI 2.0
 * Co-Simulation FMU in plain C.
 *
 * Built by tests/support/typed_build.py (which writes the modelDescription.xml with the value references
 * below) for tests/engine/test_fmi_types.py. For each type T in that order (j = 0..4) there is an input
 * u_T (value reference 10 + j) and an output y_T (20 + j). Outputs change only in fmi2DoStep (no
 * direct feedthrough). After n steps (n = 0 in initialization):
 *   echo = true:  y_T = the value of u_T when the last step started (at initialization: u_T now);
 *   echo = false: y_Real = start + 0.25 n, y_Integer = k - 7919 n, y_Boolean = (n mod 3 == 0),
 *                 y_String = "<label>|<n>", y_Enumeration = first at n = 0, then 1, 2, 5, -3 cyclically.
 * Parameters: 0 echo (Boolean), 1 label (String), 2 start (Real), 3 k (Integer), 4 first (Enumeration).
 */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef MODEL_GUID
#error "compile with -DMODEL_GUID=\"...\" (tests/support/typed_build.py does)"
#endif

enum { T_REAL, T_INT, T_BOOL, T_STR, T_ENUM, N_TYPES };
enum { VR_ECHO, VR_LABEL, VR_START, VR_K, VR_FIRST, N_PARAMS };
#define VR_IN 10
#define VR_OUT 20
#define N_VARS (VR_OUT + N_TYPES)
typedef enum { NONE, PARAMETER, INPUT, OUTPUT } Causality;

typedef struct {
    int type; /* T_INT also for Enumeration variables' storage: see is_int() */
    Causality causality;
    double r;
    int i;
    char *s;
} Var;

typedef struct {
    fmi2CallbackFunctions cb;
    fmi2String name;
    int initialized;
    long n;
    double time;
    Var v[N_VARS];
} Unit;

static const int ITEMS[4] = {1, 2, 5, -3};

static void say(Unit *u, fmi2Status status, const char *fmt, ...) {
    char text[512];
    va_list ap;
    if (u->cb.logger == NULL) return;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    u->cb.logger(u->cb.componentEnvironment, u->name, status, "logStatusError", "%s", text);
}

static fmi2Status refuse(fmi2Component c, const char *function) {
    say((Unit *)c, fmi2Error, "%s is not supported by this FMU", function);
    return fmi2Error;
}

static int set_string(Var *x, const char *s) {
    char *text = malloc(strlen(s != NULL ? s : "") + 1);
    if (text == NULL) return 0;
    strcpy(text, s != NULL ? s : "");
    free(x->s);
    x->s = text;
    return 1;
}

static void update(Unit *u) {
    int j;
    Var *y = &u->v[VR_OUT];
    char text[600];
    if (u->v[VR_ECHO].i) {
        for (j = 0; j < N_TYPES; j++) {
            y[j].r = u->v[VR_IN + j].r;
            y[j].i = u->v[VR_IN + j].i;
            set_string(&y[j], u->v[VR_IN + j].s);
        }
        return;
    }
    y[T_REAL].r = u->v[VR_START].r + 0.25 * (double)u->n;
    y[T_INT].i = u->v[VR_K].i - 7919 * (int)u->n;
    y[T_BOOL].i = u->n % 3 == 0;
    snprintf(text, sizeof text, "%s|%ld", u->v[VR_LABEL].s, u->n);
    set_string(&y[T_STR], text);
    y[T_ENUM].i = u->n == 0 ? u->v[VR_FIRST].i : ITEMS[u->n % 4];
}

/* Integer functions serve Integer and Enumeration variables. */
static Var *find(Unit *u, fmi2ValueReference vr, int type, const char *function, int set) {
    Var *x;
    if (vr >= N_VARS || u->v[vr].causality == NONE ||
        !(u->v[vr].type == type || (type == T_INT && u->v[vr].type == T_ENUM))) {
        say(u, fmi2Error, "%s: no variable of this type with value reference %u", function, vr);
        return NULL;
    }
    x = &u->v[vr];
    if (set && !(x->causality == INPUT || (x->causality == PARAMETER && !u->initialized))) {
        say(u, fmi2Error, "%s: value reference %u cannot be set now", function, vr);
        return NULL;
    }
    return x;
}

#define ACCESSORS(NAME, CTYPE, TCODE, GET, STORE)                                                              \
    fmi2Status fmi2Get##NAME(fmi2Component c, const fmi2ValueReference vr[], size_t n, CTYPE v[]) {            \
        Unit *u = (Unit *)c;                                                                                     \
        size_t k;                                                                                                \
        for (k = 0; k < n; k++) {                                                                                \
            Var *x = find(u, vr[k], TCODE, "fmi2Get" #NAME, 0);                                                  \
            if (x == NULL) return fmi2Error;                                                                     \
            v[k] = GET;                                                                                          \
        }                                                                                                        \
        return fmi2OK;                                                                                           \
    }                                                                                                            \
    fmi2Status fmi2Set##NAME(fmi2Component c, const fmi2ValueReference vr[], size_t n, const CTYPE v[]) {      \
        Unit *u = (Unit *)c;                                                                                     \
        size_t k;                                                                                                \
        for (k = 0; k < n; k++) {                                                                                \
            Var *x = find(u, vr[k], TCODE, "fmi2Set" #NAME, 1);                                                  \
            if (x == NULL) return fmi2Error;                                                                     \
            STORE;                                                                                               \
        }                                                                                                        \
        if (!u->initialized) update(u);                                                                          \
        return fmi2OK;                                                                                           \
    }

ACCESSORS(Real, fmi2Real, T_REAL, x->r, x->r = v[k])
ACCESSORS(Integer, fmi2Integer, T_INT, x->i, x->i = v[k])
ACCESSORS(Boolean, fmi2Boolean, T_BOOL, x->i, x->i = v[k] ? 1 : 0)
ACCESSORS(String, fmi2String, T_STR, x->s, if (!set_string(x, v[k])) return fmi2Error)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)c; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi2OK;
}

static void declare(Unit *u, int vr, int type, Causality causality) {
    u->v[vr].type = type;
    u->v[vr].causality = causality;
    set_string(&u->v[vr], "");
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Unit *u;
    int j;
    (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    if (fmuType != fmi2CoSimulation || fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) return NULL;
    u = calloc(1, sizeof *u);
    if (u == NULL) return NULL;
    u->cb = *functions;
    u->name = instanceName;
    declare(u, VR_ECHO, T_BOOL, PARAMETER);
    declare(u, VR_LABEL, T_STR, PARAMETER);
    declare(u, VR_START, T_REAL, PARAMETER);
    declare(u, VR_K, T_INT, PARAMETER);
    declare(u, VR_FIRST, T_ENUM, PARAMETER);
    set_string(&u->v[VR_LABEL], "typed");
    u->v[VR_FIRST].i = 1;
    for (j = 0; j < N_TYPES; j++) {
        declare(u, VR_IN + j, j, INPUT);
        declare(u, VR_OUT + j, j, OUTPUT);
    }
    u->v[VR_IN + T_ENUM].i = 1;
    update(u);
    return u;
}

void fmi2FreeInstance(fmi2Component c) {
    Unit *u = (Unit *)c;
    int k;
    if (u == NULL) return;
    for (k = 0; k < N_VARS; k++) free(u->v[k].s);
    free(u);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((Unit *)c)->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    update((Unit *)c);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Unit *u = (Unit *)c;
    update(u);
    u->initialized = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return refuse(c, "fmi2Reset"); }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Unit *u = (Unit *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!u->initialized) return refuse(c, "fmi2DoStep before initialization");
    u->time = currentCommunicationPoint + communicationStepSize;
    u->n += 1;
    update(u);
    return fmi2OK;
}

/* ---- everything else is refused (fmpy loads every FMI 2.0 function) ------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return refuse(c, "fmi2GetFMUstate"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return refuse(c, "fmi2SetFMUstate"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return refuse(c, "fmi2FreeFMUstate"); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)s; (void)size; return refuse(c, "fmi2SerializedFMUstateSize");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size) {
    (void)s; (void)b; (void)size; return refuse(c, "fmi2SerializeFMUstate");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate *s) {
    (void)s; (void)b; (void)size; return refuse(c, "fmi2DeSerializeFMUstate");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return refuse(c, "fmi2GetDirectionalDerivative");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value; return refuse(c, "fmi2SetRealInputDerivatives");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value; return refuse(c, "fmi2GetRealOutputDerivatives");
}
fmi2Status fmi2CancelStep(fmi2Component c) { return refuse(c, "fmi2CancelStep"); }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    (void)s; (void)v; return refuse(c, "fmi2GetStatus");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    (void)s; (void)v; return refuse(c, "fmi2GetRealStatus");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    (void)s; (void)v; return refuse(c, "fmi2GetIntegerStatus");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    (void)s; (void)v; return refuse(c, "fmi2GetBooleanStatus");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    (void)s; (void)v; return refuse(c, "fmi2GetStringStatus");
}
