/* exact.c - closed-form pieces and event location: a port of fmus/exact.py (see exact.h).
 *
 * Each function carries the Python it ports in its comment; expressions keep
 * Python's operation order (C and Python associate + - * / alike) and
 * complex expressions go through the dfwb_cx_* operations, which compute
 * what CPython's complex type computes. Every loop is bounded as in Python.
 */
#include "exact.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dfwb_core.h"

/* -- errors ------------------------------------------------------------------------- */
int dfwb_fail(dfwb_err *err, int code, const char *fmt, ...)
{
    if (err->code != DFWB_OK) /* the first refusal stands (Python stops at it) */
        return err->code;
    err->code = code;
    if (err->buf != NULL && err->len > 0) {
        va_list args;
        va_start(args, fmt);
        vsnprintf(err->buf, err->len, fmt, args);
        va_end(args);
    }
    return code;
}

/* repr(float): the shortest digits that read back as x (the correctly rounded %.*e of glibc, tried
 * from 1 to 17 digits), laid out as CPython's float_repr_style 'short' does: exponent notation
 * when the decimal point is more than 16 places right or 4 left of the first digit ('1e+16',
 * '1e-05'), else positional with at least one digit after the point ('1e+15' -> '1000000000000000.0').
 * Locale-proof: digits and exponent are read from the %e text, the point is always '.'. */
void dfwb_repr(double x, char out[DFWB_REPR_SIZE])
{
    char text[40], digits[20];
    int n = 0, exponent = 0, decpt, pos = 0, i;
    const char *c;
    if (isnan(x)) {
        strcpy(out, "nan");
        return;
    }
    if (isinf(x)) {
        strcpy(out, x > 0 ? "inf" : "-inf");
        return;
    }
    if (x == 0.0) {
        strcpy(out, signbit(x) ? "-0.0" : "0.0");
        return;
    }
    for (i = 1; i <= 17; i++) {
        snprintf(text, sizeof text, "%.*e", i - 1, x);
        if (strtod(text, NULL) == x)
            break;
    }
    for (c = text; *c != '\0' && *c != 'e'; c++)
        if (*c >= '0' && *c <= '9' && n < 18)
            digits[n++] = *c;
    if (*c == 'e')
        exponent = atoi(c + 1);
    while (n > 1 && digits[n - 1] == '0')
        n--;
    digits[n] = '\0';
    decpt = exponent + 1; /* x = 0.d1d2... * 10^decpt */
    if (signbit(x))
        out[pos++] = '-';
    if (decpt <= -4 || decpt > 16) {
        out[pos++] = digits[0];
        if (n > 1) {
            out[pos++] = '.';
            for (i = 1; i < n; i++)
                out[pos++] = digits[i];
        }
        snprintf(out + pos, DFWB_REPR_SIZE - (size_t)pos, "e%c%02d", exponent < 0 ? '-' : '+',
                 exponent < 0 ? -exponent : exponent);
        return;
    }
    if (decpt <= 0) {
        out[pos++] = '0';
        out[pos++] = '.';
        for (i = 0; i < -decpt; i++)
            out[pos++] = '0';
        for (i = 0; i < n; i++)
            out[pos++] = digits[i];
    } else if (decpt >= n) {
        for (i = 0; i < n; i++)
            out[pos++] = digits[i];
        for (i = n; i < decpt; i++)
            out[pos++] = '0';
        out[pos++] = '.';
        out[pos++] = '0';
    } else {
        for (i = 0; i < n; i++) {
            if (i == decpt)
                out[pos++] = '.';
            out[pos++] = digits[i];
        }
    }
    out[pos] = '\0';
}

/* -- complex numbers: CPython's complex type (make, real, add, sub, mul: inline in exact.h) ---------------- */

/* _Py_c_quot: divide top and bottom by the larger of b.re, b.im (Smith). b = 0 never occurs here
 * (the solvers divide by lam + i nu with nu > 0); it gives 0, NaN b gives NaN, as CPython. */
dfwb_cx dfwb_cx_div(dfwb_cx a, dfwb_cx b)
{
    const double abs_re = b.re < 0 ? -b.re : b.re;
    const double abs_im = b.im < 0 ? -b.im : b.im;
    if (abs_re >= abs_im) {
        if (abs_re == 0.0)
            return dfwb_cx_make(0.0, 0.0);
        {
            const double ratio = b.im / b.re;
            const double denom = b.re + b.im * ratio;
            return dfwb_cx_make((a.re + a.im * ratio) / denom, (a.im - a.re * ratio) / denom);
        }
    }
    if (abs_im >= abs_re) {
        const double ratio = b.re / b.im;
        const double denom = b.re * ratio + b.im;
        return dfwb_cx_make((a.re * ratio + a.im) / denom, (a.im * ratio - a.re) / denom);
    }
    return dfwb_cx_make(NAN, NAN);
}

/* cmath.exp for finite z (the solvers' arguments are i * a bounded phase) */
dfwb_cx dfwb_cx_exp(dfwb_cx z)
{
    const double l = exp(z.re);
    return dfwb_cx_make(l * cos(z.im), l * sin(z.im));
}

/* abs(complex): hypot; OverflowError("absolute value too large") in Python when it overflows */
double dfwb_cx_abs(dfwb_cx z, dfwb_err *err)
{
    double r;
    if (!isfinite(z.re) || !isfinite(z.im)) {
        if (isinf(z.re) || isinf(z.im))
            return INFINITY;
        return NAN;
    }
    r = hypot(z.re, z.im);
    if (!isfinite(r) && err->overflow == NULL)
        err->overflow = "absolute value too large";
    return r;
}

/* float ** float as CPython's float_pow computes it for the solvers' arguments (a finite base, an
 * integral exponent): pow() of |x|, the sign restored, OverflowError when the result overflows.
 * Called through a volatile pointer so that the compiler cannot rewrite pow(x, 2.0) as x * x. */
double dfwb_pow(double x, double y, dfwb_err *err)
{
    double (*volatile libm_pow)(double, double) = pow;
    int negate = 0;
    double r;
    if (y == 0.0)
        return 1.0;
    if (isnan(x) || isnan(y) || isinf(x) || isinf(y))
        return libm_pow(x, y);
    if (x == 0.0)
        return fmod(y, 2.0) != 0.0 ? x : 0.0; /* y > 0 and integral here: x ** odd keeps the sign */
    if (x < 0.0) {
        x = -x;
        negate = fmod(y, 2.0) != 0.0;
    }
    if (x == 1.0)
        return negate ? -1.0 : 1.0;
    r = libm_pow(x, y);
    if (negate)
        r = -r;
    if (isinf(r) && err->overflow == NULL)
        err->overflow = "(34, 'Numerical result out of range')";
    return r;
}

/* -- phi functions -------------------------------------------------------------------- */
static double factorial(int k) { return k <= 1 ? 1.0 : (k == 2 ? 2.0 : 6.0); }

/* phi_k(-y) = sum_n (-y)^n / (n + k)!, for y >= 0 (k = 1, 2, 3). */
double dfwb_phi_real(int k, double y)
{
    double value;
    int j, n;
    if (k == 1 && y > 0.0)
        return -expm1(-y) / y; /* expm1 keeps every digit */
    if (y < 0.5) {
        double term = 1.0 / factorial(k), total = term;
        for (n = 1; n < 30; n++) { /* y < 0.5: the 30th term is below 1e-40 of the first */
            term *= -y / (double)(n + k);
            total += term;
            if (fabs(term) <= 1e-18 * fabs(total))
                break;
        }
        return total;
    }
    value = -expm1(-y) / y; /* phi_1 */
    for (j = 1; j < k; j++)
        value = (1.0 / factorial(j) - value) / y; /* phi_{j+1}(-y) */
    return value;
}

/* (exp(i y) - 1) / (i y) = sin(y)/y + i 2 sin(y/2)^2 / y: no cancellation, exact as y -> 0. */
dfwb_cx dfwb_phi1_imaginary(double y)
{
    double half;
    if (y == 0.0)
        return dfwb_cx_make(1.0, 0.0);
    half = sin(0.5 * y);
    return dfwb_cx_make(sin(y) / y, 2.0 * half * half / y);
}

/* -- Drive ---------------------------------------------------------------------------- */
void dfwb_drive_init(dfwb_drive *d, double f, double F, double omega, double phi)
{
    if (F < 0.0) { /* a negative amplitude is a phase shift of pi (towards 0: |phi| does not grow) */
        F = -F;
        phi = phi <= 0.0 ? phi + DFWB_PI : phi - DFWB_PI;
    }
    d->f = f;
    d->F = F;
    d->omega = omega;
    d->phi = phi;
}

/* omega t + phi; refused naming ``name`` beyond PHASE_LIMIT, where a period is no longer resolved. */
int dfwb_drive_phase(const dfwb_drive *d, double t, const char *name, double *theta, dfwb_err *err)
{
    char rt[DFWB_REPR_SIZE], rtheta[DFWB_REPR_SIZE], rlimit[DFWB_REPR_SIZE];
    *theta = d->omega * t + d->phi;
    if (!(fabs(*theta) <= DFWB_PHASE_LIMIT)) {
        dfwb_repr(t, rt);
        dfwb_repr(*theta, rtheta);
        dfwb_repr((DFWB_PHASE_LIMIT - d->phi) / d->omega, rlimit);
        return dfwb_fail(err, DFWB_E_VALUE,
                         "%s = %s is out of range: the phase omega*t + phi = %s rad must stay within +-"
                         DFWB_PHASE_LIMIT_TEXT " rad (t <= %s s), where a float still resolves a period",
                         name, rt, rtheta, rlimit);
    }
    return DFWB_OK;
}

double dfwb_drive_u(const dfwb_drive *d, double t) { return d->f + d->F * cos(d->omega * t + d->phi); }

/* Rounding of u - level at phase theta (a phase carries |theta| ulp), scaled term by term. */
static double drive_rounding(const dfwb_drive *d, double theta, double level)
{
    const double e = 8.0 * DFWB_EPS;
    return e * fabs(d->f) + e * d->F * (1.0 + fabs(theta)) + e * fabs(level);
}

/* Whether u > level just after t; within rounding of the level the trend decides. */
int dfwb_drive_above(const dfwb_drive *d, double t, double level)
{
    const double diff = dfwb_drive_u(d, t) - level, theta = d->omega * t + d->phi;
    double slope;
    if (d->F == 0.0 || fabs(diff) > drive_rounding(d, theta, level))
        return diff > 0.0; /* a constant force has no trend: equal is not above */
    slope = -sin(theta);
    return fabs(slope) > 1e-12 ? slope > 0.0 : -cos(theta) > 0.0;
}

/* Whether u < level just after t (see dfwb_drive_above). */
int dfwb_drive_below(const dfwb_drive *d, double t, double level)
{
    const double diff = dfwb_drive_u(d, t) - level, theta = d->omega * t + d->phi;
    double slope;
    if (d->F == 0.0 || fabs(diff) > drive_rounding(d, theta, level))
        return diff < 0.0;
    slope = -sin(theta);
    return fabs(slope) > 1e-12 ? slope < 0.0 : -cos(theta) < 0.0;
}

/* First t > t0 where u crosses level upwards (or downwards); tangency is no crossing; inf if never. */
int dfwb_drive_crossing(const dfwb_drive *d, double t0, double level, int rising, double *t, dfwb_err *err)
{
    double r, theta_c, theta, n;
    int i, rc;
    char rt[DFWB_REPR_SIZE], rlevel[DFWB_REPR_SIZE], romega[DFWB_REPR_SIZE];
    *t = INFINITY;
    if (d->F == 0.0)
        return DFWB_OK;
    r = (level - d->f) / d->F;
    if (!(-1.0 < r && r < 1.0))
        return DFWB_OK;
    theta_c = rising ? -acos(r) : acos(r);
    rc = dfwb_drive_phase(d, t0, "t", &theta, err);
    if (rc != DFWB_OK)
        return rc;
    n = ceil((theta - theta_c) / DFWB_TWO_PI);
    for (i = 0; i < 3; i++) { /* n, n + 1, n + 2 */
        *t = (theta_c + DFWB_TWO_PI * (n + (double)i) - d->phi) / d->omega;
        if (*t > t0)
            return DFWB_OK;
    }
    dfwb_repr(t0, rt);
    dfwb_repr(level, rlevel);
    dfwb_repr(d->omega, romega);
    return dfwb_fail(err, DFWB_E_LIMIT,
                     "t = %s: no crossing of %s N found past it at omega = %s rad/s "
                     "(the phase does not resolve a period)", rt, rlevel, romega);
}

/* -- Motion --------------------------------------------------------------------------- */
static const dfwb_cx I1 = {0.0, 1.0};      /* 1j */
static const dfwb_cx NEG_I1 = {-0.0, -1.0}; /* -1j */

void dfwb_motion_init(dfwb_motion *m, double t0, double x0, double v0, double lam, double a, double b,
                      double omega, double phi)
{
    m->t0 = t0;
    m->x0 = x0;
    m->v0 = v0;
    m->lam = lam;
    m->a = a;
    m->b = b;
    m->omega = omega;
    m->phi = phi;
    /* b / complex(lam, omega) * cmath.exp(1j * (omega * t0 + phi)) */
    m->P = dfwb_cx_mul(dfwb_cx_div(dfwb_cx_real(b), dfwb_cx_make(lam, omega)),
                       dfwb_cx_exp(dfwb_cx_mul(I1, dfwb_cx_real(omega * t0 + phi))));
}

/* cmath.exp(1j * w * tau) */
static dfwb_cx rotation(double w, double tau)
{
    return dfwb_cx_exp(dfwb_cx_mul(dfwb_cx_mul(I1, dfwb_cx_real(w)), dfwb_cx_real(tau)));
}

/* Position and velocity at t >= t0. */
void dfwb_motion_state(const dfwb_motion *m, double t, double *x, double *v)
{
    const double tau = t - m->t0, lam = m->lam, w = m->omega;
    double p1, p2, decay;
    dfwb_cx e, h;
    if (lam == 0.0) { /* undamped: phi_k(0) = 1/k! */
        p1 = 1.0;
        p2 = 0.5;
        decay = 1.0;
    } else {
        p1 = dfwb_phi_real(1, lam * tau);
        p2 = dfwb_phi_real(2, lam * tau);
        decay = exp(-lam * tau);
    }
    e = rotation(w, tau);
    *v = m->v0 * decay + m->a * tau * p1 + dfwb_cx_mul(m->P, dfwb_cx_sub(e, dfwb_cx_real(decay))).re;
    /* (self._P * (tau * phi1_imaginary(w * tau) - tau * p1)).real */
    h = dfwb_cx_sub(dfwb_cx_mul(dfwb_cx_real(tau), dfwb_phi1_imaginary(w * tau)), dfwb_cx_real(tau * p1));
    *x = m->x0 + m->v0 * tau * p1 + m->a * tau * tau * p2 + dfwb_cx_mul(m->P, h).re;
}

double dfwb_motion_velocity(const dfwb_motion *m, double t)
{
    const double tau = t - m->t0, lam = m->lam;
    double p1, decay;
    if (lam == 0.0) {
        p1 = 1.0;
        decay = 1.0;
    } else {
        p1 = dfwb_phi_real(1, lam * tau);
        decay = exp(-lam * tau);
    }
    return m->v0 * decay + m->a * tau * p1
           + dfwb_cx_mul(m->P, dfwb_cx_sub(rotation(m->omega, tau), dfwb_cx_real(decay))).re;
}

double dfwb_motion_acceleration(const dfwb_motion *m, double t, double v)
{
    return -m->lam * v + m->a + m->b * cos(m->omega * t + m->phi);
}

/* v'' = lam^2 (v0 - a/lam - Re P) exp(-lam tau) - omega^2 Re(P exp(i omega tau)): the transient's
 * part decays, so a search long after a fast initial decay is not held to the initial scale. */
double dfwb_motion_curvature_bound(const dfwb_motion *m, int has_t, double t, dfwb_err *err)
{
    const double lam = m->lam, P = dfwb_cx_abs(m->P, err);
    double transient = lam * lam * (fabs(m->v0) + P) + lam * fabs(m->a);
    if (has_t && transient != 0.0) /* Python: `if t is not None and transient` (NaN is true) */
        transient *= exp(-lam * (t - m->t0));
    return transient + P * dfwb_pow(m->omega, 2.0, err);
}

/* Integral of x from t0 to t. */
double dfwb_motion_integral(const dfwb_motion *m, double t, dfwb_err *err)
{
    const double tau = t - m->t0, lam = m->lam, w = m->omega;
    /* (tau * phi1_imaginary(w * tau) - tau) / (1j * w) - tau * tau * phi_real(2, lam * tau) */
    const dfwb_cx harmonic = dfwb_cx_sub(
        dfwb_cx_div(dfwb_cx_sub(dfwb_cx_mul(dfwb_cx_real(tau), dfwb_phi1_imaginary(w * tau)), dfwb_cx_real(tau)),
                    dfwb_cx_mul(I1, dfwb_cx_real(w))),
        dfwb_cx_real(tau * tau * dfwb_phi_real(2, lam * tau)));
    return m->x0 * tau + m->v0 * tau * tau * dfwb_phi_real(2, lam * tau)
           + m->a * dfwb_pow(tau, 3.0, err) * dfwb_phi_real(3, lam * tau) + dfwb_cx_mul(m->P, harmonic).re;
}

/* [int_{t0}^{t} x(s) exp(-i k omega s) ds for k = 1..harmonics], given x, v at t: integration by
 * parts through the equation of motion; every exponential a power of exp(-i omega t0) or exp(-i omega t). */
void dfwb_motion_fourier(const dfwb_motion *m, double t, int harmonics, double x1, double v1, dfwb_cx *out)
{
    const double w = m->omega, t0 = m->t0;
    const dfwb_cx z0 = dfwb_cx_exp(dfwb_cx_mul(dfwb_cx_mul(NEG_I1, dfwb_cx_real(w)), dfwb_cx_real(t0)));
    const dfwb_cx z1 = dfwb_cx_exp(dfwb_cx_mul(dfwb_cx_mul(NEG_I1, dfwb_cx_real(w)), dfwb_cx_real(t)));
    const dfwb_cx half_rot = dfwb_cx_mul(dfwb_cx_real(0.5), dfwb_cx_exp(dfwb_cx_mul(I1, dfwb_cx_real(m->phi))));
    const dfwb_cx half_rot_c = dfwb_cx_make(half_rot.re, -half_rot.im);
    const double a = m->a, b = m->b, lam = m->lam, x0 = m->x0, v0 = m->v0;
    dfwb_cx below = dfwb_cx_real(t - t0); /* int exp(-i (k - 1) w s) ds, for k = 1 */
    dfwb_cx e0 = z0, e1 = z1;             /* exp(-i k w t0), exp(-i k w t) */
    int k;
    for (k = 1; k <= harmonics; k++) {
        const double nu = (double)k * w;
        const dfwb_cx n0 = dfwb_cx_mul(e0, z0), n1 = dfwb_cx_mul(e1, z1); /* power k + 1 */
        const dfwb_cx s0 = dfwb_cx_div(dfwb_cx_sub(e1, e0), dfwb_cx_mul(NEG_I1, dfwb_cx_real(nu)));
        const dfwb_cx above = dfwb_cx_div(dfwb_cx_sub(n1, n0), dfwb_cx_mul(NEG_I1, dfwb_cx_real(nu + w)));
        /* int cos(w s + phi) exp(-i k w s) ds */
        const dfwb_cx c = dfwb_cx_add(dfwb_cx_mul(half_rot, below), dfwb_cx_mul(half_rot_c, above));
        /* (a * s0 + b * c - (v1 * e1 - v0 * e0)) / complex(lam, nu) */
        const dfwb_cx j = dfwb_cx_div(
            dfwb_cx_sub(dfwb_cx_add(dfwb_cx_mul(dfwb_cx_real(a), s0), dfwb_cx_mul(dfwb_cx_real(b), c)),
                        dfwb_cx_sub(dfwb_cx_mul(dfwb_cx_real(v1), e1), dfwb_cx_mul(dfwb_cx_real(v0), e0))),
            dfwb_cx_make(lam, nu));
        /* (j - (x1 * e1 - x0 * e0)) / (1j * nu) */
        out[k - 1] = dfwb_cx_div(
            dfwb_cx_sub(j, dfwb_cx_sub(dfwb_cx_mul(dfwb_cx_real(x1), e1), dfwb_cx_mul(dfwb_cx_real(x0), e0))),
            dfwb_cx_mul(I1, dfwb_cx_real(nu)));
        below = s0;
        e0 = n0;
        e1 = n1;
    }
}

/* -- first_root ------------------------------------------------------------------------- */
void dfwb_stack_free(dfwb_stack *s)
{
    free(s->data);
    s->data = NULL;
    s->cap = 0;
}

static int stack_reserve(dfwb_stack *s, size_t n, dfwb_err *err)
{
    size_t cap;
    double *data;
    if (n <= s->cap)
        return DFWB_OK;
    cap = s->cap ? 2 * s->cap : 64;
    while (cap < n)
        cap *= 2;
    data = (double *)realloc(s->data, cap * 3 * sizeof(double));
    if (data == NULL)
        return dfwb_fail(err, DFWB_E_MEMORY, "out of memory (the event search's %lu pending points)",
                         (unsigned long)n);
    s->data = data;
    s->cap = cap;
    return DFWB_OK;
}

static int unresolved(double a, double b, double K, dfwb_err *err)
{
    char ra[DFWB_REPR_SIZE], rb[DFWB_REPR_SIZE], rK[DFWB_REPR_SIZE];
    dfwb_repr(a, ra);
    dfwb_repr(b, rb);
    dfwb_repr(K, rK);
    return dfwb_fail(err, DFWB_E_LIMIT,
                     "an event search between t = %s and t = %s s needed more than %d evaluations (curvature "
                     "bound %s): the motion cannot be resolved at the plant's scale",
                     ra, rb, DFWB_MAX_EVALUATIONS, rK);
}

/* Python's min(x, y) and max(x, y): the first unless the second is smaller (larger). */
static double py_min(double x, double y) { return y < x ? y : x; }
static double py_max(double x, double y) { return y > x ? y : x; }

/* Zero of a strictly decreasing g on [lo, hi], g(lo) > 0 >= g(hi), in at most ``budget`` evaluations. */
static int refine(dfwb_search_fun fun, const void *ctx, double lo, double hi, double g_lo, double dg_lo,
                  long budget, double K, double *root, dfwb_err *err)
{
    const double start = lo;
    double t = dg_lo < 0.0 ? lo - g_lo / dg_lo : 0.5 * (lo + hi);
    long i;
    for (i = 0; i < budget; i++) {
        double g, dg, nxt;
        if (!(lo < t && t < hi)) {
            t = 0.5 * (lo + hi);
            if (!(lo < t && t < hi)) {
                *root = hi; /* bracket at machine resolution */
                return DFWB_OK;
            }
        }
        fun(ctx, t, &g, &dg);
        if (g > 0.0)
            lo = t;
        else
            hi = t;
        nxt = dg < 0.0 ? t - g / dg : 0.5 * (lo + hi);
        if (fabs(nxt - t) <= 2.0 * DFWB_EPS * fabs(t)) {
            *root = py_min(py_max(nxt, lo), hi);
            return DFWB_OK;
        }
        t = nxt;
    }
    return unresolved(start, hi, K, err);
}

/* first_root of fmus/exact.py: intervals are cleared by rigorous bounds (positive lower bound, or g
 * increasing) and split otherwise, so a zero can never hide between two samples; a strictly decreasing
 * interval with a sign change is refined by safeguarded Newton. Each pass evaluates g once or pops a
 * point; more than MAX_EVALUATIONS evaluations (search and refinement together) are refused. */
int dfwb_first_root(dfwb_search_fun fun, dfwb_search_bound bound, const void *ctx, double a, double b, double K,
                    dfwb_stack *stack, int *found, double *root, dfwb_err *err)
{
    double ga, dga, end = b;
    size_t n;
    long evaluations = 2;
    int rc;
    *found = 0;
    fun(ctx, a, &ga, &dga);
    if (ga <= 0.0) {
        *found = 1;
        *root = a;
        return DFWB_OK;
    }
    if (bound != NULL)
        K = bound(ctx, a, err);
    rc = stack_reserve(stack, 1, err);
    if (rc != DFWB_OK)
        return rc;
    stack->data[0] = b;
    fun(ctx, b, &stack->data[1], &stack->data[2]);
    n = 1;
    while (n > 0) {
        double *top = stack->data + 3 * (n - 1);
        const double bb = top[0], gb = top[1], dgb = top[2];
        const double span = bb - a, mean_slope = 0.5 * (dga + dgb);
        int cleared;
        if (gb <= 0.0 && mean_slope + 0.5 * K * span < 0.0) {
            *found = 1;
            return refine(fun, ctx, a, bb, ga, dga, DFWB_MAX_EVALUATIONS - evaluations, K, root, err);
        }
        cleared = gb > 0.0 && (py_min(ga, gb) - 0.125 * K * span * span > 0.0
                               || mean_slope - 0.5 * K * span >= 0.0);
        if (!cleared) {
            const double m = a + 0.5 * span;
            if (a < m && m < bb) {
                if (evaluations >= DFWB_MAX_EVALUATIONS)
                    return unresolved(a, end, K, err);
                evaluations += 1;
                rc = stack_reserve(stack, n + 1, err);
                if (rc != DFWB_OK)
                    return rc;
                top = stack->data + 3 * n;
                top[0] = m;
                fun(ctx, m, &top[1], &top[2]);
                n += 1;
                continue;
            }
            if (gb <= 0.0) { /* interval at machine resolution */
                *found = 1;
                *root = bb;
                return DFWB_OK;
            }
        }
        n -= 1;
        a = bb;
        ga = gb;
        dga = dgb;
        if (bound != NULL)
            K = bound(ctx, a, err);
    }
    return DFWB_OK;
}
