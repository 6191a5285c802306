/*
 * BouncingBall: a ball falling onto the floor, FMI 2.0 Model Exchange; built by tests/support/me_build.py.
 *
 *   h' = v,   v' = -g,   h(0) = h0, v(0) = 0                         [m, m/s]
 *
 * State event: the indicator z = h crosses zero; at the event, if h <= 0 and v < 0, the ball
 * bounces: v := -e v, h := 0, `bounces` counts up and `t_bounce` holds the event's time.
 * With max_bounces > 0 the FMU asks to terminate the simulation at that bounce.
 * Analytic impacts: t_1 = sqrt(2 h0 / g), t_(k+1) = t_k + 2 e^k sqrt(2 g h0) / g.
 */

#define N_REAL 9
#define N_INT 2
#define N_STATES 2
#define N_INDICATORS 1

#include "fmi2Functions.h"

enum { VR_H, VR_V, VR_DER_H, VR_DER_V, VR_G, VR_E, VR_H0, VR_T_BOUNCE, VR_V_BEFORE };
enum { VR_BOUNCES, VR_MAX_BOUNCES };

static const fmi2ValueReference STATE_VR[N_STATES] = {VR_H, VR_V};
static const fmi2ValueReference DERIVATIVE_VR[N_STATES] = {VR_DER_H, VR_DER_V};

#include "fmi2_frame.h"

static void model_defaults(Instance *m) {
    m->r[VR_G] = 9.81;
    m->r[VR_E] = 0.7;
    m->r[VR_H0] = 1.0;
    m->r[VR_H] = m->r[VR_H0];
    m->r[VR_V] = 0.0;
    m->r[VR_T_BOUNCE] = -1.0;
    m->r[VR_V_BEFORE] = 0.0;
    m->i[VR_BOUNCES] = 0;
    m->i[VR_MAX_BOUNCES] = 0;
}

static void model_initialize(Instance *m) {
    m->r[VR_H] = m->r[VR_H0];
    m->r[VR_V] = 0.0;
    m->next_event_defined = false;
}

static void model_derivatives(Instance *m) {
    m->r[VR_DER_H] = m->r[VR_V];
    m->r[VR_DER_V] = -m->r[VR_G];
}

static void model_indicators(Instance *m, double *z) { z[0] = m->r[VR_H]; }

static void model_event(Instance *m) {
    if (m->r[VR_H] <= 0.0 && m->r[VR_V] < 0.0) {
        m->r[VR_V_BEFORE] = m->r[VR_V];
        m->r[VR_H] = 0.0;
        m->r[VR_V] = -m->r[VR_E] * m->r[VR_V];
        m->r[VR_T_BOUNCE] = m->time;
        m->i[VR_BOUNCES] += 1;
        m->values_changed = true;
        say(m, fmi2OK, "logEvents", "bounce %d at t = %.17g s", (int)m->i[VR_BOUNCES], m->time);
        if (m->i[VR_MAX_BOUNCES] > 0 && m->i[VR_BOUNCES] >= m->i[VR_MAX_BOUNCES]) m->terminate = true;
    }
}

static const char *model_check(Instance *m) { (void)m; return NULL; }
