/* integrated.c - the integrated solver family: a port of fmus/integrated.py (Trajectory and what the closed
 * loops' IntegratedMode shares with it). See integrated.h; every expression follows the Python one's order. */
#include <math.h>
#include <string.h>

#include "integrated.h"

const double dfwb_in_c[7] = {0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0};
const double dfwb_in_a[7][6] = {
    {0},
    {1.0 / 5.0},
    {3.0 / 40.0, 9.0 / 40.0},
    {44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0},
    {19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0},
    {9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0},
    {35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0},
};
const double dfwb_in_e[7] = {71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                             22.0 / 525.0, -1.0 / 40.0};
const double dfwb_in_d[7] = {-12715105075.0 / 11282082432.0, 0.0, 87487479700.0 / 32700410799.0,
                             -10690763975.0 / 1880347072.0, 701980252875.0 / 199316789632.0,
                             -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0};

double dfwb_in_gauss_nodes[DFWB_IN_GAUSS], dfwb_in_gauss_weights[DFWB_IN_GAUSS], dfwb_in_gauss_roots[DFWB_IN_GAUSS];
static int gauss_ready;

/* _legendre(n, z): P_n(z), and P_n'(z) into *dp, by the three-term recurrence. */
static double legendre(int n, double z, double *dp)
{
    double p0 = 1.0, p1 = z;
    int k;
    for (k = 2; k <= n; k++) {
        const double p2 = ((double)(2 * k - 1) * z * p1 - (double)(k - 1) * p0) / (double)k;
        p0 = p1;
        p1 = p2;
    }
    *dp = (double)n * (z * p1 - p0) / (z * z - 1.0);
    return p1;
}

/* _gauss_legendre(9): Newton on P_n from Chebyshev-like guesses, as the Python does, step by step. */
void dfwb_in_setup(void)
{
    const int n = DFWB_IN_GAUSS;
    int i, it;
    if (gauss_ready)
        return;
    for (i = 1; i <= n; i++) {
        double z = cos(DFWB_PI * ((double)i - 0.25) / ((double)n + 0.5)), dp;
        for (it = 0; it < 100; it++) {
            const double step = legendre(n, z, &dp) / dp;
            z -= step;
            if (fabs(step) <= 4.0 * DFWB_EPS)
                break;
        }
        legendre(n, z, &dp); /* P_n' at the final node */
        dfwb_in_gauss_roots[i - 1] = z;
        dfwb_in_gauss_nodes[i - 1] = 0.5 * (1.0 - z);
        dfwb_in_gauss_weights[i - 1] = 1.0 / ((1.0 - z * z) * dp * dp);
    }
    gauss_ready = 1;
}

double dfwb_in_quintic(double y0, const double c[5], double theta)
{
    const double t2 = theta * theta, t3 = t2 * theta, one = 1.0 - theta;
    return y0 + (c[0] * t3 * (10.0 - 15.0 * theta + 6.0 * t2) + c[1] * theta * one * one * (1.0 + 2.0 * theta
                 - 3.0 * t2) + c[2] * 0.5 * t2 * one * one * one + c[3] * t3 * (-4.0 + 7.0 * theta - 3.0 * t2)
                 + c[4] * 0.5 * t3 * one * one);
}

double dfwb_in_poly(double y0, const double r[4], double theta)
{
    const double one = 1.0 - theta;
    return y0 + theta * (r[0] + one * (r[1] + theta * (r[2] + one * r[3])));
}

double dfwb_in_max3(double a, double b, double c)
{
    double m = a;
    if (b > m)
        m = b;
    if (c > m)
        m = c;
    return m;
}

double dfwb_in_min3(double a, double b, double c)
{
    double m = a;
    if (b < m)
        m = b;
    if (c < m)
        m = c;
    return m;
}

double dfwb_in_feature_step(double scale, double v, double rate)
{
    /* max(0.5 * (abs(v) - NEAR * scale), 0.25 * scale) / abs(rate) */
    const double far = 0.5 * (fabs(v) - DFWB_IN_NEAR * scale), near = 0.25 * scale;
    return rate != 0.0 ? (near > far ? near : far) / fabs(rate) : INFINITY;
}

double dfwb_in_ratio(double error, double scale)
{
    return scale != 0.0 ? fabs(error) / scale : (error == 0.0 ? 0.0 : INFINITY);
}

int dfwb_in_control(dfwb_in_attempt attempt, void *ctx, double a, double *h, double *factor, const char *what,
                    const char *why, dfwb_err *err)
{
    double ratio = INFINITY;
    int it, broke = 0; /* the loop ended by a break (Python's for ... else) */
    *factor = INFINITY;
    for (it = 0; it < DFWB_IN_MAX_REJECTIONS; it++) {
        const double floor_t = fabs(a) > 1.0 ? fabs(a) : 1.0;
        if (!(*h > DFWB_IN_STEP_FLOOR * DFWB_EPS * floor_t) || !(a + *h > a)) {
            broke = 1; /* ratio stays what it was */
            break;
        }
        ratio = attempt(ctx, *h);
        if (ratio == 0.0)
            *factor = DFWB_IN_GROW;
        else {
            const double y = DFWB_IN_SAFETY * pow(ratio, -0.2), m = y > DFWB_IN_SHRINK ? y : DFWB_IN_SHRINK;
            *factor = m < DFWB_IN_GROW ? m : DFWB_IN_GROW;
        }
        if (ratio <= 1.0) {
            broke = 1;
            break;
        }
        *h *= *factor;
    }
    if (!broke)
        ratio = INFINITY;
    if (!(ratio <= 1.0)) {
        char ra[DFWB_REPR_SIZE];
        dfwb_repr(a, ra);
        return dfwb_fail(err, DFWB_E_VALUE, "the integrated %s at t = %s s: its step fell below 64 ulp of the time "
                         "(%s)", what, ra, why);
    }
    return DFWB_OK;
}

int dfwb_in_stop(dfwb_in_fun fun, const void *ctx, double g0, double floor_g, double limit, int left,
                 double *theta)
{
    int armed = g0 > floor_g, positive = g0 > 0.0, j;
    double pos_theta = 0.0, pos_g = g0;
    if (g0 < -floor_g && left) {
        *theta = 0.0;
        return 1;
    }
    for (j = 1; j <= DFWB_IN_EVENT_SAMPLES; j++) {
        const double th = (double)j / (double)DFWB_IN_EVENT_SAMPLES;
        double g;
        if ((double)(j - 1) / (double)DFWB_IN_EVENT_SAMPLES >= limit)
            return 0;
        g = fun(ctx, th);
        if (g <= 0.0 && (armed || g < -floor_g)) {
            *theta = positive ? dfwb_in_illinois(fun, ctx, pos_theta, pos_g, th, g) : left ? 0.0 : th;
            return 1;
        }
        if (g > 0.0) {
            positive = 1;
            pos_theta = th;
            pos_g = g;
            armed = armed || g > floor_g;
        }
    }
    return 0;
}

double dfwb_in_illinois(dfwb_in_fun fun, const void *ctx, double lo, double g_lo, double hi, double g_hi)
{
    int side = 0, i;
    if (g_hi == 0.0)
        return hi;
    for (i = 0; i < DFWB_IN_REFINE_ITERATIONS; i++) {
        double mid = hi - g_hi * (hi - lo) / (g_hi - g_lo), g;
        if (!(lo < mid && mid < hi)) {
            mid = 0.5 * (lo + hi);
            if (!(lo < mid && mid < hi))
                break;
        }
        g = fun(ctx, mid);
        if (g > 0.0) {
            lo = mid;
            g_lo = g;
            if (side == 1)
                g_hi *= 0.5;
            side = 1;
        } else {
            hi = mid;
            g_hi = g;
            if (side == -1)
                g_lo *= 0.5;
            side = -1;
            if (g == 0.0)
                break;
        }
        if (hi - lo <= 2.0 * DFWB_EPS * (hi > 1.0 ? hi : 1.0))
            break;
    }
    return hi;
}

/* -- the trajectory ------------------------------------------------------------------------------------ */
void dfwb_traj_init(dfwb_trajectory *tr, dfwb_law_fn law, const void *plant, double t0, double x0, double v0,
                    int sign, double omega, int harmonics, double rtol, double scale, double v_error)
{
    int k;
    dfwb_in_setup();
    memset(tr, 0, sizeof *tr);
    tr->t0 = t0;
    tr->x0 = x0;
    tr->v0 = v0;
    tr->sign = sign;
    tr->omega = omega;
    tr->harmonics = harmonics;
    tr->rtol = rtol;
    tr->scale = scale;
    tr->max_step = DFWB_TWO_PI / omega / DFWB_IN_STEPS_PER_PERIOD;
    tr->h = tr->max_step / 64.0;
    tr->k_last = law(plant, sign, t0, v0);
    tr->peak[0] = 0.0;
    tr->peak[1] = fabs(v0);
    tr->error[0] = 0.0;
    tr->error[1] = v_error;
    tr->has_stopped = 0;
    tr->stopped = 0.0;
    tr->taken = 0;
    tr->a = t0;
    tr->sh = 0.0;
    tr->d0 = 0.0;
    tr->sv0 = v0;
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++)
        tr->integrals[k] = dfwb_cx_make(0.0, 0.0);
    tr->int_err = 0.0;
    tr->pos_err = 0.0;
}

/* _dense: d and v of the last step at t */
static void dense(const dfwb_trajectory *tr, double t, double *d, double *v)
{
    double theta;
    if (!(tr->sh != 0.0)) {
        *d = tr->d0;
        *v = tr->sv0;
        return;
    }
    theta = (t - tr->a) / tr->sh;
    *d = dfwb_in_quintic(tr->d0, tr->quintic, theta);
    *v = dfwb_in_poly(tr->sv0, tr->vc, theta);
}

/* _step_integrals(step, harmonics, t): the step's start's integrals plus Gauss on [a, t], as a centre node and
 * DFWB_IN_GAUSS_PAIRS pairs mid -+ z half whose exponentials are the centre's times exp(+-i omega z half) */
static void step_integrals(const dfwb_trajectory *tr, int harmonics, double t, dfwb_cx *out)
{
    static const dfwb_cx NEG_I = {-0.0, -1.0}; /* -1j */
    const double a = tr->a, span = t - a, half = 0.5 * span, mid = a + half;
    double d, v, centre, sums[DFWB_IN_GAUSS_PAIRS], differences[DFWB_IN_GAUSS_PAIRS];
    dfwb_cx turns[DFWB_IN_GAUSS_PAIRS], powers[DFWB_IN_GAUSS_PAIRS], centre_turn, turn_k;
    int k, j;
    for (k = 0; k <= harmonics; k++)
        out[k] = tr->integrals[k];
    if (!(span > 0.0) || !(tr->sh != 0.0))
        return;
    dense(tr, mid, &d, &v);
    centre = (tr->x0 + d) * dfwb_in_gauss_weights[DFWB_IN_GAUSS_PAIRS] * span;
    out[0] = dfwb_cx_add(out[0], dfwb_cx_real(centre));
    for (j = 0; j < DFWB_IN_GAUSS_PAIRS; j++) {
        const double z = dfwb_in_gauss_roots[j], weight = dfwb_in_gauss_weights[j];
        double low, high;
        dense(tr, mid - half * z, &d, &v);
        low = (tr->x0 + d) * weight * span;
        dense(tr, mid + half * z, &d, &v);
        high = (tr->x0 + d) * weight * span;
        out[0] = dfwb_cx_add(out[0], dfwb_cx_real(low + high));
        sums[j] = low + high;
        differences[j] = low - high;
    }
    if (!harmonics)
        return;
    for (j = 0; j < DFWB_IN_GAUSS_PAIRS; j++)
        powers[j] = turns[j] = dfwb_cx_exp(dfwb_cx_make(0.0, tr->omega * (half * dfwb_in_gauss_roots[j])));
    centre_turn = dfwb_cx_exp(dfwb_cx_mul(dfwb_cx_mul(NEG_I, dfwb_cx_real(tr->omega)), dfwb_cx_real(mid)));
    turn_k = centre_turn;
    for (k = 1; k <= harmonics; k++) {
        dfwb_cx acc = dfwb_cx_make(centre, 0.0);
        for (j = 0; j < DFWB_IN_GAUSS_PAIRS; j++) {
            acc.re = acc.re + sums[j] * powers[j].re;
            acc.im = acc.im + differences[j] * powers[j].im;
        }
        out[k] = dfwb_cx_add(out[k], dfwb_cx_mul(turn_k, acc));
        turn_k = dfwb_cx_mul(turn_k, centre_turn);
        for (j = 0; j < DFWB_IN_GAUSS_PAIRS; j++)
            powers[j] = dfwb_cx_mul(powers[j], turns[j]);
    }
}

typedef struct {
    const dfwb_trajectory *tr;
} stop_ctx;

static double stop_fun(const void *ctx, double theta)
{
    const dfwb_trajectory *tr = ((const stop_ctx *)ctx)->tr;
    return (double)tr->sign * dfwb_in_poly(tr->sv0, tr->vc, theta);
}

/* _take_step's attempt: the stages of one step of size h, and its error ratio */
typedef struct {
    const dfwb_trajectory *tr;
    dfwb_law_fn law;
    const void *plant;
    double a, d0, v0, k1, size;
    double kv[7], vs[7], v1, d1, err_d, err_v;
} step_try;

static double attempt_step(void *ctx, double h)
{
    step_try *s = (step_try *)ctx;
    const dfwb_trajectory *tr = s->tr;
    double sum, scale_d, scale_v, rd, rv;
    int i, j;
    s->kv[0] = s->k1;
    s->vs[0] = s->v0;
    for (i = 1; i < 7; i++) {
        sum = 0.0;
        for (j = 0; j < i; j++)
            sum += dfwb_in_a[i][j] * s->kv[j];
        s->vs[i] = s->v0 + h * sum;
        s->kv[i] = s->law(s->plant, tr->sign, s->a + dfwb_in_c[i] * h, s->vs[i]);
    }
    s->v1 = s->vs[6];
    sum = 0.0;
    for (j = 0; j < 6; j++)
        sum += dfwb_in_a[6][j] * s->vs[j];
    s->d1 = s->d0 + h * sum;
    sum = 0.0;
    for (j = 0; j < 7; j++)
        sum += dfwb_in_e[j] * s->vs[j];
    s->err_d = h * sum;
    sum = 0.0;
    for (j = 0; j < 7; j++)
        sum += dfwb_in_e[j] * s->kv[j];
    s->err_v = h * sum;
    scale_d = tr->rtol * dfwb_in_max3(tr->peak[0], fabs(s->d1), fabs(s->d0))
              + DFWB_IN_ROUNDING * h * (fabs(s->v0) + h * s->size);
    scale_v = tr->rtol * dfwb_in_max3(tr->peak[1], fabs(s->v1), fabs(s->v0)) + DFWB_IN_ROUNDING * h * s->size;
    rd = dfwb_in_ratio(s->err_d, scale_d);
    rv = dfwb_in_ratio(s->err_v, scale_v);
    return rv > rd ? rv : rd; /* max(rd, rv) */
}

/* _take_step: one accepted step past the end (or the stop within it) */
static int take_step(dfwb_trajectory *tr, dfwb_law_fn law, dfwb_law_fn size, const void *plant, dfwb_err *err)
{
    const double a = tr->a + tr->sh, d0 = tr->d0 + tr->quintic[0], v0 = tr->sv0 + tr->vc[0];
    const double k1 = tr->k_last;
    double h = dfwb_in_min3(tr->h, tr->max_step, dfwb_in_feature_step(tr->scale, v0, k1));
    const double size_a = size(plant, tr->sign, a, v0);
    double factor, *kv, *vs, v1, d1, err_d, err_v;
    double spread, dv, dd, r2d, quartic[4], dense_error, integral_error, sum;
    dfwb_cx integrals[DFWB_HARMONICS_MAX + 1];
    int j, k, rc;
    char ra[DFWB_REPR_SIZE];
    step_try s;
    s.tr = tr;
    s.law = law;
    s.plant = plant;
    s.a = a;
    s.d0 = d0;
    s.v0 = v0;
    s.k1 = k1;
    s.size = size_a;
    rc = dfwb_in_control(attempt_step, &s, a, &h, &factor, "solver cannot resolve the motion",
                         "a stiff or singular sliding law", err);
    if (rc != DFWB_OK)
        return rc;
    kv = s.kv;
    vs = s.vs;
    v1 = s.v1;
    d1 = s.d1;
    err_d = s.err_d;
    err_v = s.err_v;
    tr->taken += 1;
    spread = fabs(vs[6] - vs[5]);
    if (spread != 0.0 && h * fabs(kv[6] - kv[5]) > 3.25 * spread) {
        tr->stiff[0] += 1;
        tr->stiff[1] = 0;
        if (tr->stiff[0] >= DFWB_IN_STIFF_STEPS && h < DFWB_IN_STIFF_FRACTION * tr->max_step) {
            dfwb_repr(a, ra);
            return dfwb_fail(err, DFWB_E_VALUE, "the sliding motion at t = %s s is too stiff for the integrated "
                             "solver: its step (%.3g s) is held by the explicit pair's stability, below 0.001 of a "
                             "drive period's 1/32 (a light mass with strong damping)", ra, h);
        }
    } else {
        tr->stiff[1] += 1;
        if (tr->stiff[1] >= 6) {
            tr->stiff[0] = 0;
            tr->stiff[1] = 0;
        }
    }
    /* the dense outputs, their error, the integrals to a: as the Python, in its order */
    dv = v1 - v0;
    dd = d1 - d0;
    r2d = h * v0 - dd;
    quartic[0] = dd;
    quartic[1] = r2d;
    quartic[2] = dd - h * v1 - r2d;
    sum = 0.0;
    for (j = 0; j < 7; j++)
        sum += dfwb_in_d[j] * vs[j];
    quartic[3] = h * sum;
    {
        double quintic[5], e = 0.0;
        static const double thetas[3] = {0.25, 0.5, 0.75};
        quintic[0] = dd;
        quintic[1] = h * v0;
        quintic[2] = h * h * k1;
        quintic[3] = h * v1;
        quintic[4] = h * h * kv[6];
        for (j = 0; j < 3; j++) {
            const double q = fabs(dfwb_in_quintic(0.0, quintic, thetas[j]) - dfwb_in_poly(0.0, quartic, thetas[j]));
            if (j == 0 || q > e)
                e = q;
        }
        dense_error = e;
        step_integrals(tr, tr->harmonics, a, integrals);
        integral_error = tr->int_err + tr->pos_err * tr->sh;
        tr->error[0] = tr->error[0] + tr->error[1] * h + fabs(err_d);
        tr->error[1] = tr->error[1] + fabs(err_v);
        /* the new last step */
        tr->a = a;
        tr->sh = h;
        tr->d0 = d0;
        tr->sv0 = v0;
        for (j = 0; j < 5; j++)
            tr->quintic[j] = quintic[j];
    }
    tr->vc[0] = dv;
    tr->vc[1] = h * k1 - dv;
    tr->vc[2] = dv - h * kv[6] - tr->vc[1];
    sum = 0.0;
    for (j = 0; j < 7; j++)
        sum += dfwb_in_d[j] * kv[j];
    tr->vc[3] = h * sum;
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++)
        tr->integrals[k] = k <= tr->harmonics ? integrals[k] : dfwb_cx_make(0.0, 0.0);
    tr->int_err = integral_error;
    tr->pos_err = tr->error[0] + 1.5 * dense_error;
    tr->peak[0] = fabs(d1) > tr->peak[0] ? fabs(d1) : tr->peak[0];
    tr->peak[1] = fabs(v1) > tr->peak[1] ? fabs(v1) : tr->peak[1];
    tr->k_last = kv[6];
    tr->h = h * factor;
    /* the stop (dfwb_in_stop): the velocity against the slide's direction, from the start's own zero on */
    {
        stop_ctx ctx;
        double theta;
        ctx.tr = tr;
        if (dfwb_in_stop(stop_fun, &ctx, (double)tr->sign * v0, DFWB_IN_ROUNDING * h * size_a, 1.0,
                         tr->taken > 1, &theta)) {
            tr->has_stopped = 1;
            tr->stopped = a + h * theta;
        }
    }
    return DFWB_OK;
}

int dfwb_traj_first_zero(dfwb_trajectory *tr, dfwb_law_fn law, dfwb_law_fn size, const void *plant, double lo,
                         double hi, int *found, double *t, dfwb_err *err)
{
    long taken = 0;
    *found = 0;
    if (tr->has_stopped) {
        *found = tr->stopped <= hi;
        *t = tr->stopped;
        return DFWB_OK;
    }
    while (tr->a + tr->sh < hi) {
        int rc;
        taken += 1;
        if (taken > DFWB_IN_MAX_STEPS) {
            char rl[DFWB_REPR_SIZE], rh[DFWB_REPR_SIZE];
            dfwb_repr(lo, rl);
            dfwb_repr(hi, rh);
            return dfwb_fail(err, DFWB_E_LIMIT, "more than %d integration steps between t = %s and t = %s s: the "
                             "sliding motion is too slow to integrate (take smaller steps)", DFWB_IN_MAX_STEPS, rl, rh);
        }
        rc = take_step(tr, law, size, plant, err);
        if (rc != DFWB_OK)
            return rc;
        if (tr->has_stopped) {
            *found = tr->stopped <= hi;
            *t = tr->stopped;
            return DFWB_OK;
        }
    }
    return DFWB_OK;
}

static int in_step(const dfwb_trajectory *tr, double t, dfwb_err *err)
{
    char rt[DFWB_REPR_SIZE], ra[DFWB_REPR_SIZE], rb[DFWB_REPR_SIZE];
    if (tr->a <= t && t <= tr->a + tr->sh)
        return DFWB_OK;
    dfwb_repr(t, rt);
    dfwb_repr(tr->a, ra);
    dfwb_repr(tr->a + tr->sh, rb);
    return dfwb_fail(err, DFWB_E_VALUE, "t = %s is out of range: this integrated piece holds [%s, %s] s", rt, ra, rb);
}

int dfwb_traj_state(const dfwb_trajectory *tr, double t, double *x, double *v, dfwb_err *err)
{
    double d;
    int rc = in_step(tr, t, err);
    if (rc != DFWB_OK) {
        *x = *v = NAN;
        return rc;
    }
    dense(tr, t, &d, v);
    *x = tr->x0 + d;
    return DFWB_OK;
}

int dfwb_traj_integrals(const dfwb_trajectory *tr, double t, dfwb_cx *out, dfwb_err *err)
{
    int rc = in_step(tr, t, err), k;
    if (rc != DFWB_OK) {
        for (k = 0; k <= tr->harmonics; k++)
            out[k] = dfwb_cx_make(NAN, NAN);
        return rc;
    }
    step_integrals(tr, tr->harmonics, t, out);
    out[0] = dfwb_cx_real(out[0].re); /* complex(integral(t)): its real part */
    return DFWB_OK;
}

double dfwb_traj_integral_error(const dfwb_trajectory *tr, double t) { return tr->int_err + tr->pos_err * (t - tr->a); }

double dfwb_traj_position_error(const dfwb_trajectory *tr) { return tr->pos_err; }

double dfwb_traj_velocity_error(const dfwb_trajectory *tr, double t)
{
    return tr->has_stopped && t >= tr->stopped ? 0.0 : tr->error[1];
}
