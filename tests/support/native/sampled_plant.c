/* Classic fourth-order Runge-Kutta over one controller interval of the isolated building.
 *
 * The plant of tests/support/sampled_reference.py: q' = A q + b_ag ag(t) + b_F F(x_0, v_0) with
 * q = [x_0..x_{m-1}, v_0..v_{m-1}] (n = 2m states) and the isolators' restoring force at the
 * interval's constant current, Eq. (17) of the paper with the coefficients already evaluated at
 * that current and multiplied by the number of devices:
 *
 *     F = p[0] v_0 + p[1] x_0 + p[2] sinh(p[3] x_0)      (p = n c0(i), n k0(i), n alpha(i), beta(i))
 *
 * ag holds the ground acceleration at the 2 N + 1 times t0 + j h / 2 (sub-step ends and midpoints).
 * After every ``stride`` of the N sub-steps of length h the state and F are written to out (rows of
 * n + 1 values). Returns 0, or 1 at the first non-finite state (the rest of out is left alone).
 */
#include <math.h>

#define MAX_STATES 64

static void rhs(int n, const double *A, const double *b_ag, const double *b_F, const double *p,
                const double *q, double ag, double *dq)
{
    int m = n / 2;
    double F = p[0] * q[m] + p[1] * q[0] + p[2] * sinh(p[3] * q[0]);
    for (int r = 0; r < n; ++r) {
        const double *row = A + (long)r * n;
        double s = 0.0;
        for (int c = 0; c < n; ++c)
            s += row[c] * q[c];
        dq[r] = s + b_ag[r] * ag + b_F[r] * F;
    }
}

int plant_interval(int n, const double *A, const double *b_ag, const double *b_F, const double *p,
                   const double *ag, int N, double h, int stride, double *q, double *out)
{
    double k1[MAX_STATES], k2[MAX_STATES], k3[MAX_STATES], k4[MAX_STATES], y[MAX_STATES];
    if (n > MAX_STATES || n < 2 || N < 1 || stride < 1)
        return 2;
    int row = 0;
    for (int s = 0; s < N; ++s) {
        double a0 = ag[2 * s], am = ag[2 * s + 1], a1 = ag[2 * s + 2];
        rhs(n, A, b_ag, b_F, p, q, a0, k1);
        for (int r = 0; r < n; ++r)
            y[r] = q[r] + 0.5 * h * k1[r];
        rhs(n, A, b_ag, b_F, p, y, am, k2);
        for (int r = 0; r < n; ++r)
            y[r] = q[r] + 0.5 * h * k2[r];
        rhs(n, A, b_ag, b_F, p, y, am, k3);
        for (int r = 0; r < n; ++r)
            y[r] = q[r] + h * k3[r];
        rhs(n, A, b_ag, b_F, p, y, a1, k4);
        int finite = 1;
        for (int r = 0; r < n; ++r) {
            q[r] += h / 6.0 * (k1[r] + 2.0 * k2[r] + 2.0 * k3[r] + k4[r]);
            finite &= isfinite(q[r]);
        }
        if (!finite)
            return 1;
        if ((s + 1) % stride == 0) {
            double *o = out + (long)row * (n + 1);
            int m = n / 2;
            for (int r = 0; r < n; ++r)
                o[r] = q[r];
            o[n] = p[0] * q[m] + p[1] * q[0] + p[2] * sinh(p[3] * q[0]);
            ++row;
        }
    }
    return 0;
}
