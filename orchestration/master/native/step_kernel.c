/* The master's inner loop in C: executes the program of FMI calls and value transfers that
 * orchestration/master/algorithm.py's CouplingAlgorithm.program() describes, for a range of
 * communication steps, with the recorder's row copy and the monitor's checks after each
 * step. It makes exactly the FMI calls, in exactly the order, and the same floating-point
 * operations as the Python path (compiled with -ffp-contract=off), so both give identical
 * results; see orchestration/master/native_stepper.py.
 *
 * Nothing here interprets an FMI status: a status above fmi2Warning stops the loop and is
 * handed back to Python, where FmuUnit translates it.
 *
 * The same library formats the rows of timeseries.csv (format_csv_rows, at the end).
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

typedef int (*set_real_fn)(void *, const unsigned int *, size_t, const double *);
typedef int (*get_real_fn)(void *, const unsigned int *, size_t, double *);
typedef int (*do_step_fn)(void *, double, double, int);

enum { OP_SET = 0, OP_STEP = 1, OP_GET = 2, OP_LATCH = 3, OP_PEEK = 4 };
enum { RULE_START = 0, RULE_FRESH = 1, RULE_MEAN = 2, RULE_EXTRAPOLATED = 3, RULE_GRID = 4 };
enum { DONE = 0, FMI_FAILED = 1, MONITOR = 2 };

typedef struct {
    int64_t kind, unit, n;      /* OP_*, index of the unit, number of values */
    const unsigned int *vrs; /* value references (the unit's prepared handle) */
    double *buf;             /* the handle's value buffer */
    const int64_t *slots;       /* per value: slot in the value arrays */
    const int64_t *rules;       /* OP_SET only: per value, RULE_* */
    int64_t every, phase;       /* the op runs in the steps s with s % every == phase */
    const int64_t *dfirst;      /* OP_SET: per value j, its held drivers are dslots[dfirst[j] .. dfirst[j + 1]) */
    const int64_t *dslots;      /* (NULL: no value has drivers) */
    const int64_t *ffirst;      /* OP_SET: the drivers known before the step, fslots[ffirst[j] .. ffirst[j + 1]) */
    const int64_t *fslots;      /* (NULL: none); when one changed, the value is peeked[slot] */
    int64_t n2, out;            /* OP_PEEK: outputs to read (1) and the slot its value goes to in peeked */
    const unsigned int *vrs2;   /* OP_PEEK: the output's value reference and buffer */
    double *buf2;
} Op;

typedef struct {
    /* units */
    int64_t n_units;
    void *const *components;
    const set_real_fn *set_real;
    const get_real_fn *get_real;
    const do_step_fn *do_step;
    double *unit_time; /* as FmuUnit._time: t before a step, t + h after it */
    /* one communication step */
    int64_t n_ops;
    const Op *ops;
    /* exchanged values: latest, and the history at t, t - h, t - 2h */
    int64_t n_values;
    double *values, *now, *before, *earlier;
    double *grid;                  /* per slot: its value at its unit's last grid point (OP_LATCH, RULE_GRID) */
    double *peeked;                /* per slot: its value at t with new held inputs (OP_PEEK) */
    int64_t known;                 /* how many history entries are real */
    const double *extrapolation; /* 3 x 3 coefficients, row = min(known, 3) - 1 */
    /* time grid */
    double start, stop, step;
    int64_t n_steps;
    /* recorder (n_record == 0: none) */
    int64_t n_record;
    const int64_t *record_slots;
    double *record_time, *record_data;
    /* monitor */
    int64_t check_finite, n_limits;
    const int64_t *limit_slots;
    const double *limits;
    /* result */
    int64_t failed_op, failed_status, failed_get; /* failed_get: an OP_PEEK failed in its get (not its set) */
} Kernel;

static double time_of(const Kernel *k, int64_t step) {
    return step == k->n_steps ? k->stop : k->start + (double)step * k->step;
}

/* How many of an output's values at t, t - h, t - 2h were computed with the present held inputs
 * (as algorithm.usable_history): 1 if a driver differs between t and t - h, 2 if between t - h and t - 2h. */
static int64_t usable_history(const Kernel *k, const int64_t *drivers, int64_t n) {
    for (int64_t d = 0; d < n; ++d)
        if (k->now[drivers[d]] != k->before[drivers[d]]) return 1;
    for (int64_t d = 0; d < n; ++d)
        if (k->before[drivers[d]] != k->earlier[drivers[d]]) return 2;
    return 3;
}

/* Did one of the drivers change in this step (latest value != value at t)? */
static int jumped(const Kernel *k, const int64_t *drivers, int64_t n) {
    for (int64_t d = 0; d < n; ++d)
        if (k->values[drivers[d]] != k->now[drivers[d]]) return 1;
    return 0;
}

static int run_program(Kernel *k, int64_t step, double t, double h) {
    int64_t known = k->known < 3 ? k->known : 3;
    const double *c = k->extrapolation + 3 * (known - 1);
    for (int64_t o = 0; o < k->n_ops; ++o) {
        const Op *op = &k->ops[o];
        if (op->every > 1 && step % op->every != op->phase) continue;
        void *component = k->components[op->unit];
        int status;
        if (op->kind == OP_SET) {
            for (int64_t j = 0; j < op->n; ++j) {
                int64_t s = op->slots[j];
                switch (op->rules[j]) {
                case RULE_START: op->buf[j] = k->now[s]; break;
                case RULE_FRESH: op->buf[j] = k->values[s]; break;
                case RULE_MEAN: op->buf[j] = 0.5 * (k->now[s] + k->values[s]); break;
                case RULE_GRID: op->buf[j] = k->grid[s]; break;
                default: {
                    const double *cj = c;
                    int64_t nf = op->fslots ? op->ffirst[j + 1] - op->ffirst[j] : 0;
                    if (nf > 0 && jumped(k, op->fslots + op->ffirst[j], nf)) {
                        op->buf[j] = k->peeked[s];
                        break;
                    }
                    int64_t nd = op->dslots ? op->dfirst[j + 1] - op->dfirst[j] : 0;
                    double second = k->before[s], third = k->earlier[s];
                    if (nd > 0) {
                        int64_t usable = usable_history(k, op->dslots + op->dfirst[j], nd);
                        if (usable < 3 && nf == nd) { /* the peeked value stands in for the one at the restart */
                            cj = k->extrapolation + 3 * usable;
                            if (usable == 1) second = k->peeked[s];
                            else third = k->peeked[s];
                        } else {
                            cj = k->extrapolation + 3 * ((known < usable ? known : usable) - 1);
                        }
                    }
                    op->buf[j] = cj[0] * k->now[s] + cj[1] * second + cj[2] * third;
                }
                }
            }
            status = k->set_real[op->unit](component, op->vrs, (size_t)op->n, op->buf);
        } else if (op->kind == OP_PEEK) {
            if (!jumped(k, op->slots, op->n)) continue;
            for (int64_t j = 0; j < op->n; ++j) op->buf[j] = k->values[op->slots[j]];
            status = k->set_real[op->unit](component, op->vrs, (size_t)op->n, op->buf);
            k->failed_get = 0;
            if (status <= 1) {
                k->failed_get = 1;
                status = k->get_real[op->unit](component, op->vrs2, (size_t)op->n2, op->buf2);
                if (status <= 1) k->peeked[op->out] = op->buf2[0];
            }
        } else if (op->kind == OP_LATCH) {
            for (int64_t j = 0; j < op->n; ++j) k->grid[op->slots[j]] = k->values[op->slots[j]];
            continue;
        } else if (op->kind == OP_STEP) {
            double dt = op->every == 1 ? h : time_of(k, step + op->every) - t;
            k->unit_time[op->unit] = t;
            status = k->do_step[op->unit](component, t, dt, 1);
            if (status <= 1) k->unit_time[op->unit] = t + dt;
        } else {
            status = k->get_real[op->unit](component, op->vrs, (size_t)op->n, op->buf);
            if (status <= 1)
                for (int64_t j = 0; j < op->n; ++j) k->values[op->slots[j]] = op->buf[j];
        }
        if (status > 1) {
            k->failed_op = o;
            k->failed_status = status;
            return FMI_FAILED;
        }
    }
    size_t bytes = (size_t)k->n_values * sizeof(double);
    memcpy(k->earlier, k->before, bytes);
    memcpy(k->before, k->now, bytes);
    memcpy(k->now, k->values, bytes);
    k->known += 1;
    return DONE;
}

static int observe(Kernel *k, int64_t row, double t) {
    if (k->record_time) {
        double *out = k->record_data + row * k->n_record;
        k->record_time[row] = t;
        for (int64_t j = 0; j < k->n_record; ++j) out[j] = k->values[k->record_slots[j]];
    }
    if (k->check_finite)
        for (int64_t s = 0; s < k->n_values; ++s)
            if (!isfinite(k->values[s])) return MONITOR;
    for (int64_t j = 0; j < k->n_limits; ++j)
        if (fabs(k->values[k->limit_slots[j]]) > k->limits[j]) return MONITOR;
    return DONE;
}

/* Steps first .. last - 1 (step s goes from t(s) to t(s + 1)); *done = steps finished.
 * Returns DONE, FMI_FAILED (failed_op, failed_status set; that step is not finished) or
 * MONITOR (the step is finished and recorded; the monitor has something to say). */
int run_steps(Kernel *k, int64_t first, int64_t last, int64_t *done) {
    for (int64_t s = first; s < last; ++s) {
        double t = time_of(k, s), t_next = time_of(k, s + 1);
        int code = run_program(k, s, t, t_next - t);
        if (code != DONE) {
            *done = s;
            return code;
        }
        code = observe(k, s + 1, t_next);
        *done = s + 1;
        if (code != DONE) return code;
    }
    return DONE;
}

/* ---- timeseries.csv rows, formatted exactly as Python's '%.12g' % x ------------------------
 *
 * The fast path scales x to a 12-digit integer with one or two correctly rounded operations
 * (error below 3e-4 of a unit of the 12th digit) and rounds it; when the scaled value lies
 * within 0.01 of a rounding tie, or x is huge or tiny, it asks the C library (correctly
 * rounded, as Python is). NaN prints as "nan" whatever its sign bit, as in Python.
 */

static const double POW10[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static char *format_exact(double x, char *p) {
    char tmp[40];
    int n = snprintf(tmp, sizeof tmp, "%.12g", x);
    memcpy(p, tmp, (size_t)n);
    return p + n;
}

/* x * 10^k for |k| <= 44; 0 if out of that range (the caller then takes the exact path). */
static double scaled(double x, int k) {
    if (k >= 0 && k <= 22) return x * POW10[k];
    if (k > 22 && k <= 44) return x * 1e22 * POW10[k - 22];
    if (k < 0 && k >= -22) return x / POW10[-k];
    return 0.0;
}

static char *format_g12(double x, char *p) {
    if (isnan(x)) {
        memcpy(p, "nan", 3);
        return p + 3;
    }
    double a = fabs(x);
    if (signbit(x)) *p++ = '-';
    if (a == 0.0) {
        *p++ = '0';
        return p;
    }
    if (isinf(a)) {
        memcpy(p, "inf", 3);
        return p + 3;
    }
    if (a < 1e-30 || a > 1e30) return format_exact(a, p);
    int e = (int)floor(log10(a));
    double m = scaled(a, 11 - e);
    if (m < 1e11) m = scaled(a, 11 - --e);
    else if (m >= 1e12) m = scaled(a, 11 - ++e);
    if (!(m >= 1e11 && m < 1e12)) return format_exact(a, p);
    double whole = floor(m), frac = m - whole;
    if (fabs(frac - 0.5) < 0.01) return format_exact(a, p);
    uint64_t d = (uint64_t)whole + (frac > 0.5);
    if (d >= 1000000000000ULL) {
        d /= 10;
        e += 1;
    }
    char digits[12];
    for (int j = 11; j >= 0; --j) {
        digits[j] = (char)('0' + d % 10);
        d /= 10;
    }
    int sig = 12;
    while (sig > 1 && digits[sig - 1] == '0') --sig;
    if (e >= -4 && e < 12) {
        if (e >= 0) {
            memcpy(p, digits, (size_t)e + 1);
            p += e + 1;
            if (sig > e + 1) {
                *p++ = '.';
                memcpy(p, digits + e + 1, (size_t)(sig - e - 1));
                p += sig - e - 1;
            }
        } else {
            *p++ = '0';
            *p++ = '.';
            for (int j = 0; j < -e - 1; ++j) *p++ = '0';
            memcpy(p, digits, (size_t)sig);
            p += sig;
        }
        return p;
    }
    *p++ = digits[0];
    if (sig > 1) {
        *p++ = '.';
        memcpy(p, digits + 1, (size_t)sig - 1);
        p += sig - 1;
    }
    *p++ = 'e';
    *p++ = e < 0 ? '-' : '+';
    int ae = e < 0 ? -e : e;
    if (ae >= 100) *p++ = (char)('0' + ae / 100);
    *p++ = (char)('0' + ae / 10 % 10);
    *p++ = (char)('0' + ae % 10);
    return p;
}

/* Rows of a C-contiguous n_rows x n_cols block as CSV lines ("v,v,...,v\n") into out, which
 * holds at least n_rows * n_cols * CSV_BYTES_PER_VALUE bytes; returns the bytes written. */
#define CSV_BYTES_PER_VALUE 24
int64_t csv_bytes_per_value(void) { return CSV_BYTES_PER_VALUE; }

int64_t format_csv_rows(const double *block, int64_t n_rows, int64_t n_cols, char *out) {
    char *p = out;
    for (int64_t r = 0; r < n_rows; ++r) {
        const double *row = block + r * n_cols;
        for (int64_t c = 0; c < n_cols; ++c) {
            p = format_g12(row[c], p);
            *p++ = c + 1 < n_cols ? ',' : '\n';
        }
    }
    return (int64_t)(p - out);
}
