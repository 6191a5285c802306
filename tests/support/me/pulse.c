/*
 * Pulse: a first-order lag driven by a periodic rectangular pulse, FMI 2.0 Model Exchange;
 * built by tests/support/me_build.py. The pulse switches at time events (fmi2EventInfo.nextEventTime).
 *
 *   tau y' = level - y,   y(0) = 0                                    [1, s]
 *   level = amplitude for t_on + k period <= t < t_on + k period + width (k = 0, 1, ...), else 0
 *
 * Outputs y, level and `switches` (Integer: how many switches so far).
 */

#define N_REAL 8
#define N_INT 1
#define N_STATES 1
#define N_INDICATORS 0

#include "fmi2Functions.h"

enum { VR_Y, VR_DER_Y, VR_LEVEL, VR_TAU, VR_AMPLITUDE, VR_T_ON, VR_WIDTH, VR_PERIOD };
enum { VR_SWITCHES };

static const fmi2ValueReference STATE_VR[N_STATES] = {VR_Y};
static const fmi2ValueReference DERIVATIVE_VR[N_STATES] = {VR_DER_Y};

#include "fmi2_frame.h"

static void model_defaults(Instance *m) {
    m->r[VR_Y] = 0.0;
    m->r[VR_LEVEL] = 0.0;
    m->r[VR_TAU] = 0.2;
    m->r[VR_AMPLITUDE] = 1.0;
    m->r[VR_T_ON] = 0.1234;
    m->r[VR_WIDTH] = 0.3333;
    m->r[VR_PERIOD] = 1.0;
    m->i[VR_SWITCHES] = 0;
}

static void model_initialize(Instance *m) {
    m->r[VR_Y] = 0.0;
    m->r[VR_LEVEL] = 0.0;
    m->i[VR_SWITCHES] = 0;
    m->next_event_defined = true;
    m->next_event_time = m->r[VR_T_ON];
}

static void model_derivatives(Instance *m) {
    m->r[VR_DER_Y] = (m->r[VR_LEVEL] - m->r[VR_Y]) / m->r[VR_TAU];
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m) {
    if (!time_event_due(m)) return;
    if (m->r[VR_LEVEL] == 0.0) {  /* switch on; off after the width */
        m->r[VR_LEVEL] = m->r[VR_AMPLITUDE];
        m->next_event_time += m->r[VR_WIDTH];
    } else {                      /* switch off; on again one period after the last switch on */
        m->r[VR_LEVEL] = 0.0;
        m->next_event_time += m->r[VR_PERIOD] - m->r[VR_WIDTH];
    }
    m->i[VR_SWITCHES] += 1;
}

static const char *model_check(Instance *m) { (void)m; return NULL; }
