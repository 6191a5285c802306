/* Bouc-Wen state along a displacement path for many parameter sets, in C.
 *
 * The same scheme, operation by operation and in the same order, as
 * components/physics/bouc_wen_core.py (bouc_wen_states -> _advance -> bouc_wen_step ->
 * _lam / _exp_step): exponential-midpoint sub-steps of dy/dx = delta - lam(y) y, the state
 * clamped to the envelope after every sub-step. The caller (components/identification/
 * bouc_wen_native.py) computes what couples the batch in the numpy code: the sub-step count
 * of every sample (the largest over the batch) and the envelope of every parameter set.
 * All parameter sets then take the same sub-steps, so the loop over them is innermost and
 * is vectorised (OpenMP SIMD; pow and expm1 from glibc's libmvec when built with
 * -DBW_LIBMVEC, for AVX-512, AVX2 or SSE2 chosen when the library loads; else the scalar libm
 * functions). The caller pads the batch to whole vectors, so every set goes through the
 * same vector code and its result does not depend on the rest of the batch.
 *
 * numpy semantics are kept where they differ from C's: sign(NaN) and maximum(NaN, b) are
 * NaN, clip(NaN) is NaN. Compiled with -ffp-contract=off (no fused multiply-add; the
 * -fno-math-errno -fno-trapping-math that let the loop vectorise change no value). Results
 * equal the numpy path up to the last bits of pow and expm1 (numpy uses its own SIMD
 * versions of these two on some CPUs; tests/physics/test_bouc_wen.py bounds the difference).
 */
#include <math.h>
#include <stdint.h>

#ifdef BW_LIBMVEC
#pragma omp declare simd notinbranch
double pow(double, double);
#pragma omp declare simd notinbranch
double expm1(double);
#endif

#define TINY 1e-12 /* _TINY of bouc_wen_core: floor of |y| in |y|^(n-1) */
#define ZMAX 50.0  /* _ZMAX of bouc_wen_core: cap of the exponent of one sub-step */

static inline double np_sign(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : (v == 0.0 ? 0.0 : v)); }

static inline double np_maximum(double a, double b) { return a != a ? a : (b != b ? b : (a >= b ? a : b)); }

static inline double np_clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* _lam: (beta sign(y) + gamma s) max(|y|, floor)^(n-1) */
static inline double lam_of(double y, double s, double beta, double gamma, double n, double floor_) {
    return (beta * np_sign(y) + gamma * s) * pow(np_maximum(fabs(y), floor_), n - 1.0);
}

/* _exp_step: exact solution of dy/dx = delta - lam y over dx = h with lam frozen */
static inline double exp_step(double y, double h, double delta, double lam) {
    double z = np_clip(-lam * h, -ZMAX, ZMAX) + 1e-300;
    return y + h * (delta - lam * y) * (expm1(z) / z);
}

/* States for n_sets parameter sets along n_paths paths of n_samples samples.
 *
 * dx: (n_paths, n_samples - 1) increments; m: (n_samples - 1) sub-steps per sample;
 * beta, gamma, n, bound: (n_sets) parameters and envelope; delta, y0: shared;
 * work: (n_sets) scratch; out: (n_sets, n_paths, n_samples), row-major.
 */
#if defined(BW_LIBMVEC) && defined(__x86_64__)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
void bouc_wen_states(int64_t n_sets, int64_t n_paths, int64_t n_samples, const double *dx, const int64_t *m,
                     const double *beta, const double *gamma, const double *n, const double *bound, double delta,
                     double y0, double *work, double *out) {
    double *y = work;
    for (int64_t r = 0; r < n_paths; ++r) {
        const double *d = dx + r * (n_samples - 1);
        for (int64_t p = 0; p < n_sets; ++p) y[p] = out[(p * n_paths + r) * n_samples] = y0;
        for (int64_t k = 0; k + 1 < n_samples; ++k) {
            /* bouc_wen_step's per-sub-step quantities, shared by the batch */
            const double h = d[k] / (double)m[k], half = 0.5 * h;
            const double s = np_sign(h), floor_ = np_maximum(0.5 * fabs(delta * h), TINY);
            for (int64_t j = 0; j < m[k]; ++j) {
#pragma omp simd
                for (int64_t p = 0; p < n_sets; ++p) {
                    const double y_half = exp_step(y[p], half, delta, lam_of(y[p], s, beta[p], gamma[p], n[p], floor_));
                    const double next = exp_step(y[p], h, delta, lam_of(y_half, s, beta[p], gamma[p], n[p], floor_));
                    y[p] = np_clip(next, -bound[p], bound[p]);
                }
            }
            for (int64_t p = 0; p < n_sets; ++p) out[(p * n_paths + r) * n_samples + k + 1] = y[p];
        }
    }
}
