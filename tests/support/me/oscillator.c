/*
 * Oscillator: a damped mass-spring oscillator driven by a force, FMI 2.0 Model Exchange
 * (and Co-Simulation when compiled with -DCO_SIMULATION); built by tests/support/me_build.py.
 *
 *   x' = v,   m v' = u - c v - k x,   x(0) = x0, v(0) = v0          [m, m/s, N]
 *
 * Outputs x, v and a = v' (direct feedthrough from u); `cosim` is 1 in an instance made for
 * Co-Simulation and 0 for Model Exchange (it shows which interface the importer used).
 * fmi2GetDerivatives fails (fmi2Error, with a message) once the time passes fail_at >= 0.
 */

#define N_REAL 13
#define N_INT 0
#define N_STATES 2
#define N_INDICATORS 0

#include "fmi2Functions.h"

enum { VR_X, VR_V, VR_DER_X, VR_DER_V, VR_U, VR_M, VR_C, VR_K, VR_X0, VR_V0, VR_FAIL_AT, VR_A, VR_COSIM };

static const fmi2ValueReference STATE_VR[N_STATES] = {VR_X, VR_V};
static const fmi2ValueReference DERIVATIVE_VR[N_STATES] = {VR_DER_X, VR_DER_V};

#include "fmi2_frame.h"

static void model_defaults(Instance *m) {
    m->r[VR_M] = 1.0;
    m->r[VR_C] = 0.4;
    m->r[VR_K] = 4.0;
    m->r[VR_X0] = 1.0;
    m->r[VR_V0] = 0.0;
    m->r[VR_U] = 0.0;
    m->r[VR_FAIL_AT] = -1.0;
    m->r[VR_X] = m->r[VR_X0];
    m->r[VR_V] = m->r[VR_V0];
}

static void model_initialize(Instance *m) {
    m->r[VR_X] = m->r[VR_X0];
    m->r[VR_V] = m->r[VR_V0];
    m->next_event_defined = false;
}

static void model_derivatives(Instance *m) {
    m->r[VR_DER_X] = m->r[VR_V];
    m->r[VR_DER_V] = (m->r[VR_U] - m->r[VR_C] * m->r[VR_V] - m->r[VR_K] * m->r[VR_X]) / m->r[VR_M];
    m->r[VR_A] = m->r[VR_DER_V];
    m->r[VR_COSIM] = m->type == fmi2CoSimulation ? 1.0 : 0.0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m) { (void)m; }

static const char *model_check(Instance *m) {
    static char why[128];
    if (m->r[VR_FAIL_AT] >= 0.0 && m->time > m->r[VR_FAIL_AT]) {
        snprintf(why, sizeof why, "injected failure at t = %.17g s", m->time);
        return why;
    }
    return NULL;
}
