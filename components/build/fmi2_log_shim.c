/*
 * FMI 2.0 co-simulation shim around a pythonfmu 0.7 binary: unit errors reach every host.
 *
 * pythonfmu 0.7 forwards a message to the host's logger only when the host instantiated
 * the unit with loggingOn (and, if it named categories, only in those): a host that runs
 * without debug logging (`fmpy simulate`, most engines by default) sees no error at all,
 * not even why fmi2Instantiate failed. And a Python do_step that returns False (our
 * shells' way of failing without pythonfmu's fmi2Fatal) comes back as fmi2Discard, which
 * `fmpy simulate` and others take for "stop early" and carry on with.
 *
 * This library is the FMU's <modelIdentifier>.so; pythonfmu's library lies beside it as
 * INNER_LIBRARY (a compile-time name) and is loaded on the first fmi2Instantiate. Every
 * FMI function forwards to it, except that:
 *   - the inner instance always logs (loggingOn = true, no category filter), and the
 *     shim forwards a message of status fmi2Warning or worse always, and a plain (fmi2OK)
 *     message only when the host asked for debug logging (in its categories, if it named
 *     any), which is what the FMI standard asks of a unit;
 *   - with STEP_FAILURE_IS_ERROR, fmi2DoStep returns fmi2Error instead of fmi2Discard when
 *     the unit logged an error during the step.
 * '%' in a message is doubled: hosts treat the message as a printf format.
 *
 * Built by components/build/pythonfmu_units.py (`cc -shared -fPIC ... -ldl`).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef INNER_LIBRARY
#error "define INNER_LIBRARY, the file name of pythonfmu's library beside this one"
#endif
#ifndef STEP_FAILURE_IS_ERROR
#define STEP_FAILURE_IS_ERROR 0
#endif

#define EXPORT __attribute__((visibility("default")))

typedef struct {
    fmi2Component inner;
    fmi2CallbackFunctions host;  /* the host's callbacks (copied) */
    fmi2CallbackFunctions own;   /* handed to pythonfmu, which keeps the pointer */
    int debug;                   /* the host's loggingOn */
    size_t n_categories;
    char **categories;           /* the host's categories (none: all) */
    int error_logged;            /* the unit logged fmi2Error or worse since it was cleared */
} Shim;

/* ---- the inner library ------------------------------------------------------------- */

static void *inner_handle;
static char inner_error[4096 + 128];
static pthread_once_t inner_once = PTHREAD_ONCE_INIT;

#define INNER_FUNCTIONS(X) \
    X(fmi2SetDebugLogging) X(fmi2Instantiate) X(fmi2FreeInstance) X(fmi2SetupExperiment) \
    X(fmi2EnterInitializationMode) X(fmi2ExitInitializationMode) X(fmi2Terminate) X(fmi2Reset) \
    X(fmi2GetReal) X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString) \
    X(fmi2SetReal) X(fmi2SetInteger) X(fmi2SetBoolean) X(fmi2SetString) \
    X(fmi2GetFMUstate) X(fmi2SetFMUstate) X(fmi2FreeFMUstate) X(fmi2SerializedFMUstateSize) \
    X(fmi2SerializeFMUstate) X(fmi2DeSerializeFMUstate) X(fmi2GetDirectionalDerivative) \
    X(fmi2SetRealInputDerivatives) X(fmi2GetRealOutputDerivatives) X(fmi2DoStep) X(fmi2CancelStep) \
    X(fmi2GetStatus) X(fmi2GetRealStatus) X(fmi2GetIntegerStatus) X(fmi2GetBooleanStatus) \
    X(fmi2GetStringStatus)

#define DECLARE(name) static name##TYPE *inner_##name;
INNER_FUNCTIONS(DECLARE)
#undef DECLARE

static void load_inner(void) {
    Dl_info self;
    if (!dladdr((void *)&load_inner, &self) || self.dli_fname == NULL) {
        strcpy(inner_error, "cannot locate the FMU's own library (dladdr failed)");
        return;
    }
    const char *slash = strrchr(self.dli_fname, '/');
    size_t folder = slash ? (size_t)(slash - self.dli_fname + 1) : 0;
    char path[4096];
    if (snprintf(path, sizeof path, "%.*s%s", (int)folder, self.dli_fname, INNER_LIBRARY) >= (int)sizeof path) {
        strcpy(inner_error, "the FMU's binary folder path is too long");
        return;
    }
    void *handle = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (handle == NULL) {
        const char *why = dlerror();
        snprintf(inner_error, sizeof inner_error, "cannot load pythonfmu's library: %s", why ? why : path);
        return;
    }
#define RESOLVE(name) \
    inner_##name = (name##TYPE *)dlsym(handle, #name); \
    if (inner_##name == NULL) { \
        snprintf(inner_error, sizeof inner_error, "%s has no " #name, path); \
        dlclose(handle); \
        return; \
    }
    INNER_FUNCTIONS(RESOLVE)
#undef RESOLVE
    inner_handle = handle;
}

__attribute__((destructor)) static void unload_inner(void) {
    /* Unloaded with this library, as the host's dlclose would have unloaded pythonfmu's. */
    if (inner_handle != NULL) {
        dlclose(inner_handle);
        inner_handle = NULL;
    }
}

/* ---- logging ------------------------------------------------------------------------ */

static int wanted(const Shim *s, fmi2Status status, fmi2String category) {
    if (status >= fmi2Warning) return 1;
    if (!s->debug) return 0;
    if (s->n_categories == 0) return 1;
    for (size_t k = 0; k < s->n_categories; k++)
        if (category != NULL && strcmp(s->categories[k], category) == 0) return 1;
    return 0;
}

static void forward(const fmi2CallbackFunctions *host, fmi2String instance, fmi2Status status,
                    fmi2String category, fmi2String message) {
    if (host->logger == NULL) return;
    if (message == NULL) message = "";
    size_t percents = 0, n = strlen(message);
    for (size_t k = 0; k < n; k++) percents += message[k] == '%';
    if (percents == 0) {
        host->logger(host->componentEnvironment, instance, status, category, message);
        return;
    }
    char *escaped = malloc(n + percents + 1);
    if (escaped == NULL) {
        host->logger(host->componentEnvironment, instance, status, category, "(message with '%%' dropped: no memory)");
        return;
    }
    char *out = escaped;
    for (size_t k = 0; k < n; k++) {
        *out++ = message[k];
        if (message[k] == '%') *out++ = '%';
    }
    *out = '\0';
    host->logger(host->componentEnvironment, instance, status, category, escaped);
    free(escaped);
}

static void shim_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                        fmi2String category, fmi2String message, ...) {
    Shim *s = (Shim *)env;
    if (status >= fmi2Error) s->error_logged = 1;
    if (wanted(s, status, category)) forward(&s->host, instance, status, category, message);
}

static void shim_step_finished(fmi2ComponentEnvironment env, fmi2Status status) {
    Shim *s = (Shim *)env;
    if (s->host.stepFinished != NULL) s->host.stepFinished(s->host.componentEnvironment, status);
}

static void free_categories(Shim *s) {
    for (size_t k = 0; k < s->n_categories; k++) free(s->categories[k]);
    free(s->categories);
    s->categories = NULL;
    s->n_categories = 0;
}

/* ---- FMI 2.0 ------------------------------------------------------------------------ */

EXPORT const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
EXPORT const char *fmi2GetVersion(void) { return fmi2Version; }

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    pthread_once(&inner_once, load_inner);
    if (inner_handle == NULL) {
        if (functions != NULL)
            forward(functions, instanceName, fmi2Fatal, "logStatusFatal", inner_error);
        return NULL;
    }
    Shim *s = calloc(1, sizeof *s);
    if (s == NULL) return NULL;
    if (functions != NULL) s->host = *functions;
    s->own = s->host;
    s->own.logger = shim_logger;
    s->own.stepFinished = shim_step_finished;
    s->own.componentEnvironment = s;
    s->debug = loggingOn != fmi2False;
    s->inner = inner_fmi2Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, &s->own, visible,
                                     fmi2True);
    if (s->inner == NULL) {
        free(s);
        return NULL;
    }
    return s;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Shim *s = (Shim *)c;
    if (s == NULL) return;
    inner_fmi2FreeInstance(s->inner);
    free_categories(s);
    free(s);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                      const fmi2String categories[]) {
    Shim *s = (Shim *)c;
    free_categories(s);
    s->debug = loggingOn != fmi2False;
    if (nCategories > 0 && categories != NULL) {
        s->categories = calloc(nCategories, sizeof *s->categories);
        if (s->categories == NULL) return fmi2Error;
        for (size_t k = 0; k < nCategories; k++) {
            s->categories[k] = strdup(categories[k] ? categories[k] : "");
            if (s->categories[k] == NULL) {
                s->n_categories = k;
                free_categories(s);
                return fmi2Error;
            }
        }
        s->n_categories = nCategories;
    }
    return inner_fmi2SetDebugLogging(s->inner, fmi2True, 0, NULL);
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                             fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Shim *s = (Shim *)c;
    s->error_logged = 0;
    fmi2Status status = inner_fmi2DoStep(s->inner, currentCommunicationPoint, communicationStepSize,
                                         noSetFMUStatePriorToCurrentPoint);
    if (STEP_FAILURE_IS_ERROR && status == fmi2Discard && s->error_logged) return fmi2Error;
    return status;
}

#define INNER(c) (((Shim *)(c))->inner)

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    return inner_fmi2SetupExperiment(INNER(c), toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}
EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return inner_fmi2EnterInitializationMode(INNER(c)); }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return inner_fmi2ExitInitializationMode(INNER(c)); }
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { return inner_fmi2Terminate(INNER(c)); }
EXPORT fmi2Status fmi2Reset(fmi2Component c) { return inner_fmi2Reset(INNER(c)); }

#define GET_SET(name, type) \
    EXPORT fmi2Status name(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, type value[]) { \
        return inner_##name(INNER(c), vr, nvr, value); \
    }
GET_SET(fmi2GetReal, fmi2Real)
GET_SET(fmi2GetInteger, fmi2Integer)
GET_SET(fmi2GetBoolean, fmi2Boolean)
GET_SET(fmi2GetString, fmi2String)
GET_SET(fmi2SetReal, const fmi2Real)
GET_SET(fmi2SetInteger, const fmi2Integer)
GET_SET(fmi2SetBoolean, const fmi2Boolean)
GET_SET(fmi2SetString, const fmi2String)
#undef GET_SET

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    return inner_fmi2GetFMUstate(INNER(c), state);
}
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    return inner_fmi2SetFMUstate(INNER(c), state);
}
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    return inner_fmi2FreeFMUstate(INNER(c), state);
}
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    return inner_fmi2SerializedFMUstateSize(INNER(c), state, size);
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    return inner_fmi2SerializeFMUstate(INNER(c), state, bytes, size);
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state) {
    return inner_fmi2DeSerializeFMUstate(INNER(c), bytes, size, state);
}
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                               size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                               size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    return inner_fmi2GetDirectionalDerivative(INNER(c), vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
                                              dvUnknown);
}
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                              const fmi2Integer order[], const fmi2Real value[]) {
    return inner_fmi2SetRealInputDerivatives(INNER(c), vr, nvr, order, value);
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                               const fmi2Integer order[], fmi2Real value[]) {
    return inner_fmi2GetRealOutputDerivatives(INNER(c), vr, nvr, order, value);
}
EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return inner_fmi2CancelStep(INNER(c)); }

#define STATUS(name, type) \
    EXPORT fmi2Status name(fmi2Component c, const fmi2StatusKind s, type *value) { \
        return inner_##name(INNER(c), s, value); \
    }
STATUS(fmi2GetStatus, fmi2Status)
STATUS(fmi2GetRealStatus, fmi2Real)
STATUS(fmi2GetIntegerStatus, fmi2Integer)
STATUS(fmi2GetBooleanStatus, fmi2Boolean)
STATUS(fmi2GetStringStatus, fmi2String)
#undef STATUS
