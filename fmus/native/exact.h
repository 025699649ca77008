/* exact.h - internal: closed-form pieces and event location (port of fmus/exact.py).
 *
 * Not part of the public API (dfwb_core.h); the library is compiled with
 * -fvisibility=hidden, so none of these symbols is exported.
 *
 * Complex numbers are a struct of two doubles and every operation mirrors
 * CPython 3's complex type, term by term (a float operand is first made the
 * complex (x, 0.0), as CPython does), so that the C and Python solvers round
 * alike. cmath.exp(z) is exp(z.re) * (cos z.im, sin z.im).
 */
#ifndef DFWB_EXACT_H
#define DFWB_EXACT_H

#include <stddef.h>

#define DFWB_EPS 2.220446049250313e-16
#define DFWB_PI 3.141592653589793
#define DFWB_TWO_PI (2.0 * DFWB_PI)
#define DFWB_PHASE_LIMIT 1e10
#define DFWB_PHASE_LIMIT_TEXT "1e+10" /* f"{PHASE_LIMIT:g}" */
#define DFWB_MAX_EVALUATIONS 100000
#define DFWB_EVENTS_PER_PERIOD_LIMIT 100000
#define DFWB_STALL_EVENTS 1000 /* consecutive events within DFWB_STALL_ULPS ulp of each other (piecewise.py) */
#define DFWB_STALL_ULPS 64
#ifndef DFWB_MAX_PERIODS_PER_STEP /* the work of one step; -D at build time sets smaller bounds (tests) */
#define DFWB_MAX_PERIODS_PER_STEP 1e6
#define DFWB_MAX_PERIODS_PER_STEP_TEXT "1e+06" /* f"{MAX_PERIODS_PER_STEP:g}" */
#endif
#ifndef DFWB_MAX_EVENTS_PER_STEP
#define DFWB_MAX_EVENTS_PER_STEP 5000000
#endif

/* -- errors ------------------------------------------------------------------------- */
typedef struct {
    char *buf;              /* caller's buffer, or NULL */
    size_t len;
    int code;               /* first status reported (DFWB_OK while none) */
    const char *overflow;   /* set when a power or |z| overflowed (Python: OverflowError), its message */
} dfwb_err;

/* printf-style arguments, checked by the compiler: C99's printf (mingw-w64 builds with
   __USE_MINGW_ANSI_STDIO=1, whose printf is gnu_printf, not msvcrt's). */
#if defined(__MINGW32__)
#define DFWB_PRINTF(fmt, args) __attribute__((format(gnu_printf, fmt, args)))
#elif defined(__GNUC__) || defined(__clang__)
#define DFWB_PRINTF(fmt, args) __attribute__((format(printf, fmt, args)))
#else
#define DFWB_PRINTF(fmt, args)
#endif

/* Record a refusal (the first one wins) and return its code. printf-style message. */
int dfwb_fail(dfwb_err *err, int code, const char *fmt, ...) DFWB_PRINTF(3, 4);

/* repr(x) as Python writes a float (shortest round trip; '1e+16', '0.0001', '12.0', 'nan', '-inf'). */
#define DFWB_REPR_SIZE 32
void dfwb_repr(double x, char out[DFWB_REPR_SIZE]);

/* -- complex numbers as CPython computes them ----------------------------------------- */
typedef struct {
    double re, im;
} dfwb_cx;

/* Inline: the Fourier sums call them millions of times (inlined, the same operations and roundings). */
static inline dfwb_cx dfwb_cx_make(double re, double im)
{
    dfwb_cx z;
    z.re = re;
    z.im = im;
    return z;
}

static inline dfwb_cx dfwb_cx_real(double x) { return dfwb_cx_make(x, 0.0); } /* complex(x): (x, 0.0) */

static inline dfwb_cx dfwb_cx_add(dfwb_cx a, dfwb_cx b) { return dfwb_cx_make(a.re + b.re, a.im + b.im); }

static inline dfwb_cx dfwb_cx_sub(dfwb_cx a, dfwb_cx b) { return dfwb_cx_make(a.re - b.re, a.im - b.im); }

/* _Py_c_prod */
static inline dfwb_cx dfwb_cx_mul(dfwb_cx a, dfwb_cx b)
{
    return dfwb_cx_make(a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re);
}
dfwb_cx dfwb_cx_div(dfwb_cx a, dfwb_cx b);       /* Smith's algorithm, as _Py_c_quot */
dfwb_cx dfwb_cx_exp(dfwb_cx z);                  /* cmath.exp for a finite z */
double dfwb_cx_abs(dfwb_cx z, dfwb_err *err);    /* abs(z): hypot; overflow flagged */
double dfwb_pow(double x, double y, dfwb_err *err); /* x ** y for floats; overflow flagged */

/* -- phi functions -------------------------------------------------------------------- */
double dfwb_phi_real(int k, double y);           /* phi_k(-y), k = 1, 2, 3 */
dfwb_cx dfwb_phi1_imaginary(double y);           /* (exp(i y) - 1) / (i y) */

/* -- the force u(t) = f + F cos(omega t + phi) ------------------------------------------ */
typedef struct {
    double f, F, omega, phi;
} dfwb_drive;

void dfwb_drive_init(dfwb_drive *d, double f, double F, double omega, double phi);
int dfwb_drive_phase(const dfwb_drive *d, double t, const char *name, double *theta, dfwb_err *err);
double dfwb_drive_u(const dfwb_drive *d, double t);
int dfwb_drive_above(const dfwb_drive *d, double t, double level);
int dfwb_drive_below(const dfwb_drive *d, double t, double level);
/* First t > t0 where u crosses level upwards (rising) or downwards; inf when it never does. */
int dfwb_drive_crossing(const dfwb_drive *d, double t0, double level, int rising, double *t, dfwb_err *err);

/* -- x'' = -lam x' + a + b cos(omega t + phi) from (t0, x0, v0) ------------------------ */
typedef struct {
    double t0, x0, v0, lam, a, b, omega, phi;
    dfwb_cx P; /* particular harmonic response of the velocity: Re{P exp(i theta)} */
} dfwb_motion;

void dfwb_motion_init(dfwb_motion *m, double t0, double x0, double v0, double lam, double a, double b,
                      double omega, double phi);
void dfwb_motion_state(const dfwb_motion *m, double t, double *x, double *v);
double dfwb_motion_velocity(const dfwb_motion *m, double t); /* the v of motion_state, without x */
double dfwb_motion_acceleration(const dfwb_motion *m, double t, double v);
/* Bound on |v''| over [t, inf) (has_t) or [t0, inf) (not has_t). */
double dfwb_motion_curvature_bound(const dfwb_motion *m, int has_t, double t, dfwb_err *err);
double dfwb_motion_integral(const dfwb_motion *m, double t, dfwb_err *err);
/* out[k - 1] = int_{t0}^{t} x(s) exp(-i k omega s) ds, k = 1..harmonics, given x1, v1 at t. */
void dfwb_motion_fourier(const dfwb_motion *m, double t, int harmonics, double x1, double v1, dfwb_cx *out);

/* -- first zero of a smooth function ------------------------------------------------- */
/* g(t) and g'(t) of a search; bound(t): |g''| on [t, inf). */
typedef void (*dfwb_search_fun)(const void *ctx, double t, double *g, double *dg);
typedef double (*dfwb_search_bound)(const void *ctx, double t, dfwb_err *err);

/* The pending points of first_root, grown on demand (at most MAX_EVALUATIONS of them). */
typedef struct {
    double *data; /* 3 doubles (t, g, g') per point */
    size_t cap;   /* points */
} dfwb_stack;

void dfwb_stack_free(dfwb_stack *s);

/* First t in (a, b] where g(t) <= 0, given g(a) > 0 and |g''| <= K on [a, b] (K from bound(ctx, t) on
 * [t, b] when bound is not NULL). *found = 0 when g stays positive. Refuses (DFWB_E_LIMIT) beyond
 * MAX_EVALUATIONS evaluations. */
int dfwb_first_root(dfwb_search_fun fun, dfwb_search_bound bound, const void *ctx, double a, double b, double K,
                    dfwb_stack *stack, int *found, double *root, dfwb_err *err);

#endif /* DFWB_EXACT_H */
