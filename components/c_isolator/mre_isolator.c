/*
 * MRE base isolator as a plain-C FMI 2.0 Co-Simulation FMU (not made with pythonfmu).
 *
 * The same unit as components/shells/mre_isolator_fmu.py (class MreIsolator): same variable
 * names, value references, units, causalities and value semantics.
 *
 *   F = n * (c0(i) v + k0(i) x + alpha(i) sinh(beta(i) x) + F0),  p(i) = p_0 * i + p_1,
 *
 * with the current i clipped to [0, i_max] before it enters the law (Eq. 17 of the paper,
 * SI units). F is direct feedthrough: it is evaluated from the present inputs whenever it
 * is read. The unit has no dynamic state; its FMU state is the variable values, the
 * "outside a range" flags of the warning policy, the mode and the time.
 *
 * Range policy (as the Python unit): |x| > x_identified, |x| > x_limit and a current
 * outside [0, i_max] each log one fmi2Warning when entered (checked in fmi2DoStep).
 *
 * Beyond the identified range (String parameter beyond_range, as
 * mre_isolator_core.bounded_force_law, same operations in the same order): 'extrapolate'
 * (default, Eq. 17 everywhere), 'tangent' (the spring continues along its tangent at
 * +-x_identified) or 'stop' ('tangent' plus a Kelvin stop at +-x_limit with k_stop [N/m] and
 * c_stop [N.s/m], never pulling). Out-of-domain parameters are logged as an error when
 * initialization ends and fail the first step (F reads NaN), as in the Python unit.
 * Non-finite inputs make fmi2DoStep return fmi2Error with a logged message
 * "input <name> = <value> is not finite at t = <t> s".
 *
 * Built by components/build/c_isolator.py against the FMI 2.0 headers fmpy ships:
 *   cc -shared -fPIC -O2 -ffp-contract=off -I<fmpy>/c-code mre_isolator.c -lm
 * The builder defines MODEL_GUID and the Table 2 defaults (from
 * components/mre_isolator_core.TABLE2, the same doubles as the Python unit) at the top
 * of the file it compiles and ships in the FMU's sources/; the values below are only
 * for compiling this file alone.
 */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef MODEL_GUID
#define MODEL_GUID "{mre-isolator-c-standalone}"
#endif

/* Table 2 of the paper converted to SI (N/mm -> N/m etc.: x1000; alpha unchanged). */
#ifndef DEFAULT_K0_0
#define DEFAULT_K0_0 (5.8161 / 1e-3)
#endif
#ifndef DEFAULT_K0_1
#define DEFAULT_K0_1 (3.3431 / 1e-3)
#endif
#ifndef DEFAULT_C0_0
#define DEFAULT_C0_0 (0.5767 / 1e-3)
#endif
#ifndef DEFAULT_C0_1
#define DEFAULT_C0_1 (0.3396 / 1e-3)
#endif
#ifndef DEFAULT_ALPHA_0
#define DEFAULT_ALPHA_0 4.9810
#endif
#ifndef DEFAULT_ALPHA_1
#define DEFAULT_ALPHA_1 8.1100
#endif
#ifndef DEFAULT_BETA_0
#define DEFAULT_BETA_0 (0.1322 / 1e-3)
#endif
#ifndef DEFAULT_BETA_1
#define DEFAULT_BETA_1 (0.3463 / 1e-3)
#endif
#ifndef DEFAULT_I_MAX
#define DEFAULT_I_MAX 3.0
#endif
#ifndef DEFAULT_X_IDENTIFIED
#define DEFAULT_X_IDENTIFIED 0.008
#endif
#ifndef DEFAULT_X_LIMIT
#define DEFAULT_X_LIMIT 0.015
#endif
#ifndef DEFAULT_N_ISOLATORS
#define DEFAULT_N_ISOLATORS 2
#endif
#ifndef DEFAULT_K_STOP
#define DEFAULT_K_STOP 5.0e6
#endif
#ifndef DEFAULT_C_STOP
#define DEFAULT_C_STOP 12047.178237241671
#endif

/* Value references: the same as the pythonfmu unit's. */
enum {
    VR_X = 0, VR_V, VR_I,
    VR_K0_0, VR_K0_1, VR_C0_0, VR_C0_1, VR_ALPHA_0, VR_ALPHA_1, VR_BETA_0, VR_BETA_1,
    VR_F0, VR_N_ISOLATORS, VR_I_MAX, VR_X_IDENTIFIED, VR_X_LIMIT,
    VR_F,
    VR_BEYOND_RANGE, VR_K_STOP, VR_C_STOP, /* added after F, as in the Python unit */
    VR_F_OFF, /* the force at 0 A: added last, as in the Python unit */
    N_VR
};

/* beyond_range: the policies of mre_isolator_core.BEYOND_RANGE, and an unknown text. */
enum { BEYOND_EXTRAPOLATE, BEYOND_TANGENT, BEYOND_STOP, BEYOND_UNKNOWN };
static const char *const BEYOND_NAMES[] = {"extrapolate", "tangent", "stop"};
#define BEYOND_TEXT_MAX 64

typedef enum { MODE_INSTANTIATED, MODE_INITIALIZATION, MODE_STEP, MODE_TERMINATED, MODE_ERROR } Mode;

enum { OUT_IDENTIFIED, OUT_LIMIT, OUT_CURRENT, N_OUT };

/* Everything fmi2GetFMUstate saves: a plain struct, so a state is a copy of it. */
typedef struct {
    double real[N_VR];      /* Real variables by value reference (F, F_off, n_isolators, beyond_range unused) */
    fmi2Integer n_isolators;
    int beyond;             /* BEYOND_* */
    char beyond_text[BEYOND_TEXT_MAX]; /* the String as set (truncated if longer) */
    int failed;             /* parameters out of their domain when initialization ended */
    int outside[N_OUT];     /* inside/outside each range at the last step (warn on entry) */
    Mode mode;
    double time;            /* last communication point reached */
} ModelState;

typedef struct {
    ModelState s;
    char *name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
} Instance;

#define STATE_MAGIC 0x4d524543u /* "MREC" */

typedef struct {
    unsigned magic;
    unsigned size;
} StateHeader;

static const char *const VR_NAMES[N_VR] = {
    "x", "v", "i", "k0_0", "k0_1", "c0_0", "c0_1", "alpha_0", "alpha_1", "beta_0", "beta_1",
    "F0", "n_isolators", "i_max", "x_identified", "x_limit", "F", "beyond_range", "k_stop", "c_stop",
    "F_off",
};

/* -- logging -------------------------------------------------------------------------- */

static void log_message(const Instance *inst, fmi2Status status, const char *fmt, ...) {
    char buffer[512];
    const char *category;
    va_list args;
    /* Warnings and errors are always reported; plain messages only with debug logging on. */
    if (inst->logger == NULL || (status == fmi2OK && !inst->logging_on)) {
        return;
    }
    va_start(args, fmt);
    vsnprintf(buffer, sizeof buffer, fmt, args);
    va_end(args);
    switch (status) {
    case fmi2Warning: category = "logStatusWarning"; break;
    case fmi2Discard: category = "logStatusDiscard"; break;
    case fmi2Error: category = "logStatusError"; break;
    case fmi2Fatal: category = "logStatusFatal"; break;
    default: category = "logAll"; break;
    }
    /* The message goes through "%s": the logger formats printf-style. */
    inst->logger(inst->env, inst->name, status, category, "%s", buffer);
}

static fmi2Status fail(Instance *inst, const char *function, const char *what) {
    log_message(inst, fmi2Error, "%s: %s", function, what);
    return fmi2Error;
}

static int allowed(Instance *inst, const char *function, unsigned mask) {
    if (inst == NULL) {
        return 0;
    }
    if (mask & (1u << inst->s.mode)) {
        return 1;
    }
    log_message(inst, fmi2Error, "%s is not allowed in the present mode (%d)", function, (int)inst->s.mode);
    return 0;
}

#define M(mode) (1u << (mode))
#define ANY_MODE (M(MODE_INSTANTIATED) | M(MODE_INITIALIZATION) | M(MODE_STEP) | M(MODE_TERMINATED) | M(MODE_ERROR))

/* -- the model ------------------------------------------------------------------------ */

static void set_defaults(ModelState *s) {
    memset(s, 0, sizeof *s);
    s->real[VR_K0_0] = DEFAULT_K0_0;
    s->real[VR_K0_1] = DEFAULT_K0_1;
    s->real[VR_C0_0] = DEFAULT_C0_0;
    s->real[VR_C0_1] = DEFAULT_C0_1;
    s->real[VR_ALPHA_0] = DEFAULT_ALPHA_0;
    s->real[VR_ALPHA_1] = DEFAULT_ALPHA_1;
    s->real[VR_BETA_0] = DEFAULT_BETA_0;
    s->real[VR_BETA_1] = DEFAULT_BETA_1;
    s->real[VR_F0] = 0.0;
    s->real[VR_I_MAX] = DEFAULT_I_MAX;
    s->real[VR_X_IDENTIFIED] = DEFAULT_X_IDENTIFIED;
    s->real[VR_X_LIMIT] = DEFAULT_X_LIMIT;
    s->real[VR_K_STOP] = DEFAULT_K_STOP;
    s->real[VR_C_STOP] = DEFAULT_C_STOP;
    s->n_isolators = DEFAULT_N_ISOLATORS;
    s->beyond = BEYOND_EXTRAPOLATE;
    strcpy(s->beyond_text, BEYOND_NAMES[BEYOND_EXTRAPOLATE]);
    s->mode = MODE_INSTANTIATED;
}

/* Why the parameters are out of their domain (written to why), or 0 if they are not: the checks
 * of mre_isolator_core.bounded_force_law, in its order. */
static int parameter_problem(const ModelState *s, char *why, size_t size) {
    const double *r = s->real;
    const int stop = s->beyond == BEYOND_STOP;
    if (s->beyond == BEYOND_UNKNOWN) {
        snprintf(why, size, "beyond_range = '%s' is not one of 'extrapolate', 'tangent', 'stop'", s->beyond_text);
        return 1;
    }
    if (s->beyond == BEYOND_EXTRAPOLATE) {
        return 0;
    }
    if (!(r[VR_X_IDENTIFIED] > 0.0)) {
        snprintf(why, size, "x_identified = %.17g m must be > 0", r[VR_X_IDENTIFIED]);
        return 1;
    }
    if (stop && !(r[VR_X_LIMIT] > r[VR_X_IDENTIFIED])) {
        snprintf(why, size, "x_limit = %.17g m must exceed x_identified = %.17g m", r[VR_X_LIMIT],
                 r[VR_X_IDENTIFIED]);
        return 1;
    }
    if (stop && !(r[VR_K_STOP] >= 0.0)) {
        snprintf(why, size, "k_stop = %.17g N/m must not be negative", r[VR_K_STOP]);
        return 1;
    }
    if (stop && !(r[VR_C_STOP] >= 0.0)) {
        snprintf(why, size, "c_stop = %.17g N.s/m must not be negative", r[VR_C_STOP]);
        return 1;
    }
    return 0;
}

/* The current as it enters the law: clipped to [0, i_max] (NaN passes, as in Python). */
static double clipped_current(const ModelState *s) {
    double i = s->real[VR_I];
    if (i < 0.0) {
        i = 0.0;
    }
    if (i > s->real[VR_I_MAX]) {
        i = s->real[VR_I_MAX];
    }
    return i;
}

/* Eq. (17) with the beyond_range policy: the same operations in the same order as
 * mre_isolator_core.force_law (inside +-x_identified, or 'extrapolate') and bounded_force_law
 * (beyond it), at the current i (clipped; 0 for F_off). C's sinh/cosh overflow to +-inf where Python's safe_sinh/safe_cosh give +-inf. */
static double force_at(const ModelState *s, double i) {
    const double *r = s->real;
    const double x = r[VR_X];
    const double v = r[VR_V];
    const double xb = r[VR_X_IDENTIFIED];
    const double n = (double)s->n_isolators;
    const double c0 = r[VR_C0_0] * i + r[VR_C0_1];
    const double k0 = r[VR_K0_0] * i + r[VR_K0_1];
    const double alpha = r[VR_ALPHA_0] * i + r[VR_ALPHA_1];
    const double beta = r[VR_BETA_0] * i + r[VR_BETA_1];
    double ax, sign, edge, spring, f, contact;
    char why[256];
    if (s->failed || (s->mode != MODE_STEP && parameter_problem(s, why, sizeof why))) {
        return NAN; /* as the Python unit: no force from parameters out of their domain */
    }
    ax = fabs(x);
    if (s->beyond == BEYOND_EXTRAPOLATE || ax <= xb) {
        return n * (c0 * v + k0 * x + alpha * sinh(beta * x) + r[VR_F0]);
    }
    sign = x > 0.0 ? 1.0 : -1.0;
    edge = sign * xb;
    spring = k0 * edge + alpha * sinh(beta * edge) + (k0 + alpha * beta * cosh(beta * xb)) * (x - edge);
    f = n * (c0 * v + spring + r[VR_F0]);
    if (s->beyond == BEYOND_STOP && ax > r[VR_X_LIMIT]) {
        contact = r[VR_K_STOP] * (ax - r[VR_X_LIMIT]) + r[VR_C_STOP] * sign * v;
        if (contact > 0.0) {
            f += sign * contact;
        }
    }
    return f;
}

static void warn_on_entry(Instance *inst, int key, int outside, const char *fmt, ...) {
    if (outside && !inst->s.outside[key] && inst->logger != NULL) {
        char buffer[512];
        va_list args;
        va_start(args, fmt);
        vsnprintf(buffer, sizeof buffer, fmt, args);
        va_end(args);
        log_message(inst, fmi2Warning, "%s", buffer);
    }
    inst->s.outside[key] = outside;
}

/* -- common functions ----------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    static const char *const known[] = {"logStatusWarning", "logStatusDiscard", "logStatusError",
                                        "logStatusFatal", "logAll"};
    Instance *inst = (Instance *)c;
    size_t k, j;
    if (!allowed(inst, "fmi2SetDebugLogging", ANY_MODE)) {
        return fmi2Error;
    }
    for (k = 0; k < nCategories; k++) {
        int found = 0;
        for (j = 0; j < sizeof known / sizeof known[0]; j++) {
            found |= categories[k] != NULL && strcmp(categories[k], known[j]) == 0;
        }
        if (!found) {
            return fail(inst, "fmi2SetDebugLogging", "unknown log category");
        }
    }
    inst->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance *inst;
    (void)fmuResourceLocation;
    (void)visible;
    if (instanceName == NULL || fmuGUID == NULL) {
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof *inst);
    if (inst == NULL) {
        return NULL;
    }
    inst->name = (char *)malloc(strlen(instanceName) + 1);
    if (inst->name == NULL) {
        free(inst);
        return NULL;
    }
    strcpy(inst->name, instanceName);
    if (functions != NULL) {
        inst->logger = functions->logger;
        inst->env = functions->componentEnvironment;
    }
    inst->logging_on = loggingOn ? 1 : 0;
    if (fmuType != fmi2CoSimulation) {
        log_message(inst, fmi2Error, "fmi2Instantiate: this FMU supports co-simulation only");
    } else if (strcmp(fmuGUID, MODEL_GUID) != 0) {
        log_message(inst, fmi2Error, "fmi2Instantiate: GUID %s does not match this binary (%s)", fmuGUID,
                    MODEL_GUID);
    } else {
        set_defaults(&inst->s);
        return inst;
    }
    free(inst->name);
    free(inst);
    return NULL;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst != NULL) {
        free(inst->name);
        free(inst);
    }
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *inst = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!allowed(inst, "fmi2SetupExperiment", M(MODE_INSTANTIATED))) {
        return fmi2Error;
    }
    inst->s.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2EnterInitializationMode", M(MODE_INSTANTIATED))) {
        return fmi2Error;
    }
    inst->s.mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2ExitInitializationMode", M(MODE_INITIALIZATION))) {
        return fmi2Error;
    }
    inst->s.mode = MODE_STEP;
    {
        char why[256];
        inst->s.failed = parameter_problem(&inst->s, why, sizeof why);
        if (inst->s.failed) { /* as the Python unit: logged here, and the first step fails */
            log_message(inst, fmi2Error, "invalid isolator parameters: %s", why);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = (Instance *)c;
    /* Also after an error, like the pythonfmu unit, so a failed run can be shut down cleanly. */
    if (!allowed(inst, "fmi2Terminate", M(MODE_INITIALIZATION) | M(MODE_STEP) | M(MODE_ERROR))) {
        return fmi2Error;
    }
    inst->s.mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2Reset", ANY_MODE)) {
        return fmi2Error;
    }
    set_defaults(&inst->s);
    return fmi2OK;
}

/* -- getting and setting values ------------------------------------------------------- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (!allowed(inst, "fmi2GetReal", ANY_MODE)) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] == VR_F) {
            value[k] = force_at(&inst->s, clipped_current(&inst->s));
        } else if (vr[k] == VR_F_OFF) {
            value[k] = force_at(&inst->s, 0.0);
        } else if (vr[k] < N_VR && vr[k] != VR_N_ISOLATORS && vr[k] != VR_BEYOND_RANGE) {
            value[k] = inst->s.real[vr[k]];
        } else {
            log_message(inst, fmi2Error, "fmi2GetReal: no Real variable with value reference %u", vr[k]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (!allowed(inst, "fmi2GetInteger", ANY_MODE)) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_N_ISOLATORS) {
            log_message(inst, fmi2Error, "fmi2GetInteger: no Integer variable with value reference %u", vr[k]);
            return fmi2Error;
        }
        value[k] = inst->s.n_isolators;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : fail((Instance *)c, "fmi2GetBoolean", "the unit has no Boolean variables");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (!allowed(inst, "fmi2GetString", ANY_MODE)) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_BEYOND_RANGE) {
            log_message(inst, fmi2Error, "fmi2GetString: no String variable with value reference %u", vr[k]);
            return fmi2Error;
        }
        value[k] = inst->s.beyond_text;
    }
    return fmi2OK;
}

/* Inputs may be set until the end; parameters (variability fixed) only before initialization ends. */
static int settable(Instance *inst, const char *function, fmi2ValueReference vr) {
    const int is_input = vr == VR_X || vr == VR_V || vr == VR_I;
    if (vr >= N_VR || vr == VR_F || vr == VR_F_OFF) {
        log_message(inst, fmi2Error, "%s: value reference %u is not a settable variable", function, vr);
        return 0;
    }
    if (!is_input && inst->s.mode != MODE_INSTANTIATED && inst->s.mode != MODE_INITIALIZATION) {
        log_message(inst, fmi2Error, "%s: parameter %s is fixed after initialization", function, VR_NAMES[vr]);
        return 0;
    }
    return 1;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (!allowed(inst, "fmi2SetReal", M(MODE_INSTANTIATED) | M(MODE_INITIALIZATION) | M(MODE_STEP))) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] == VR_N_ISOLATORS) {
            return fail(inst, "fmi2SetReal", "n_isolators is an Integer");
        }
        if (vr[k] == VR_BEYOND_RANGE) {
            return fail(inst, "fmi2SetReal", "beyond_range is a String");
        }
        if (!settable(inst, "fmi2SetReal", vr[k])) {
            return fmi2Error;
        }
        inst->s.real[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (!allowed(inst, "fmi2SetInteger", M(MODE_INSTANTIATED) | M(MODE_INITIALIZATION) | M(MODE_STEP))) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_N_ISOLATORS) {
            log_message(inst, fmi2Error, "fmi2SetInteger: no Integer variable with value reference %u", vr[k]);
            return fmi2Error;
        }
        if (!settable(inst, "fmi2SetInteger", vr[k])) {
            return fmi2Error;
        }
        inst->s.n_isolators = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : fail((Instance *)c, "fmi2SetBoolean", "the unit has no Boolean variables");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    int p;
    if (!allowed(inst, "fmi2SetString", M(MODE_INSTANTIATED) | M(MODE_INITIALIZATION) | M(MODE_STEP))) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_BEYOND_RANGE) {
            log_message(inst, fmi2Error, "fmi2SetString: no String variable with value reference %u", vr[k]);
            return fmi2Error;
        }
        if (!settable(inst, "fmi2SetString", vr[k])) {
            return fmi2Error;
        }
        if (value[k] == NULL) {
            return fail(inst, "fmi2SetString", "beyond_range: a NULL string");
        }
        inst->s.beyond = BEYOND_UNKNOWN; /* refused when initialization ends, as in the Python unit */
        for (p = BEYOND_EXTRAPOLATE; p < BEYOND_UNKNOWN; p++) {
            if (strcmp(value[k], BEYOND_NAMES[p]) == 0) {
                inst->s.beyond = p;
            }
        }
        snprintf(inst->s.beyond_text, sizeof inst->s.beyond_text, "%s", value[k]);
    }
    return fmi2OK;
}

/* -- FMU state ------------------------------------------------------------------------ */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    ModelState *copy;
    if (!allowed(inst, "fmi2GetFMUstate", ANY_MODE)) {
        return fmi2Error;
    }
    copy = (ModelState *)*FMUstate;
    if (copy == NULL) {
        copy = (ModelState *)malloc(sizeof *copy);
        if (copy == NULL) {
            return fail(inst, "fmi2GetFMUstate", "out of memory");
        }
    }
    *copy = inst->s;
    *FMUstate = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2SetFMUstate", ANY_MODE)) {
        return fmi2Error;
    }
    if (FMUstate == NULL) {
        return fail(inst, "fmi2SetFMUstate", "no state given");
    }
    inst->s = *(const ModelState *)FMUstate;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)c;
    if (FMUstate != NULL) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)c;
    (void)FMUstate;
    *size = sizeof(StateHeader) + sizeof(ModelState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    Instance *inst = (Instance *)c;
    StateHeader header = {STATE_MAGIC, (unsigned)sizeof(ModelState)};
    if (FMUstate == NULL || size < sizeof header + sizeof(ModelState)) {
        return fail(inst, "fmi2SerializeFMUstate", "no state or buffer too small");
    }
    memcpy(serializedState, &header, sizeof header);
    memcpy(serializedState + sizeof header, FMUstate, sizeof(ModelState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    StateHeader header;
    ModelState *copy;
    if (size != sizeof header + sizeof(ModelState)) {
        return fail(inst, "fmi2DeSerializeFMUstate", "wrong size: not a state of this FMU");
    }
    memcpy(&header, serializedState, sizeof header);
    if (header.magic != STATE_MAGIC || header.size != sizeof(ModelState)) {
        return fail(inst, "fmi2DeSerializeFMUstate", "not a state of this FMU");
    }
    copy = (ModelState *)(*FMUstate != NULL ? *FMUstate : malloc(sizeof *copy));
    if (copy == NULL) {
        return fail(inst, "fmi2DeSerializeFMUstate", "out of memory");
    }
    memcpy(copy, serializedState + sizeof header, sizeof *copy);
    *FMUstate = copy;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return fail((Instance *)c, "fmi2GetDirectionalDerivative", "not provided");
}

/* -- co-simulation -------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fail((Instance *)c, "fmi2SetRealInputDerivatives", "the unit does not interpolate inputs");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fail((Instance *)c, "fmi2GetRealOutputDerivatives", "the unit provides no output derivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    ModelState *s;
    const double t = currentCommunicationPoint;
    double ax, i;
    int k;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!allowed(inst, "fmi2DoStep", M(MODE_STEP))) {
        return fmi2Error;
    }
    s = &inst->s;
    if (s->failed) {
        char why[256];
        parameter_problem(s, why, sizeof why);
        log_message(inst, fmi2Error, "invalid isolator parameters: %s", why);
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    for (k = VR_X; k <= VR_I; k++) {
        if (!isfinite(s->real[k])) {
            log_message(inst, fmi2Error, "input %s = %g is not finite at t = %.6g s", VR_NAMES[k], s->real[k], t);
            s->mode = MODE_ERROR;
            return fmi2Error;
        }
    }
    ax = fabs(s->real[VR_X]);
    i = s->real[VR_I];
    warn_on_entry(inst, OUT_IDENTIFIED, ax > s->real[VR_X_IDENTIFIED],
                  "|x| = %.3g mm left the identified range %.3g mm at t = %.6g s: %s",
                  ax * 1e3, s->real[VR_X_IDENTIFIED] * 1e3, t,
                  s->beyond == BEYOND_EXTRAPOLATE ? "the model is extrapolated"
                                                  : "the law continues along its tangent at the boundary");
    warn_on_entry(inst, OUT_LIMIT, ax > s->real[VR_X_LIMIT],
                  "|x| = %.3g mm passed the device limit %.3g mm at t = %.6g s", ax * 1e3,
                  s->real[VR_X_LIMIT] * 1e3, t);
    warn_on_entry(inst, OUT_CURRENT, !(0.0 <= i && i <= s->real[VR_I_MAX]),
                  "current i = %.4g A left [0, %.4g] A at t = %.6g s: clipped", i, s->real[VR_I_MAX], t);
    s->time = t + communicationStepSize;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return fail((Instance *)c, "fmi2CancelStep", "fmi2DoStep never returns fmi2Pending");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    (void)c;
    return fmi2Discard; /* no asynchronous steps */
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || s != fmi2LastSuccessfulTime) {
        return fmi2Discard;
    }
    *value = inst->s.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)c;
    if (s != fmi2Terminated) {
        return fmi2Discard;
    }
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}
