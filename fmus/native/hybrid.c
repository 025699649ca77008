/* hybrid.c - exact integration of a piecewise-affine hybrid system: a port of fmus/hybrid.py (see hybrid.h).
 *
 * Each function carries the Python it ports in its comment. Sums run left to right from 0.0 as Python's
 * sum() of floats does, products and quotients keep Python's order, powers go through dfwb_pow (libm's pow,
 * as CPython's float ** int), k! is the correctly rounded double of math.factorial(k) (what float / int
 * divides by), so that both solvers round alike. Every loop is bounded as in Python.
 */
#include "hybrid.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dfwb_core.h"
#include "integrated.h"

#define TAYLOR_RADIUS 1.0
#define TAYLOR_TOLERANCE 0x1p-60
#define TREND_ROUNDING (64.0 * DFWB_EPS)
#define EVENTS_PER_CHUNK_TEXT "10000"
#define TIME_LIMIT_TEXT "1e+12"

/* float(math.factorial(k)), k = 0..41 (correctly rounded: Python divides a float by the exact integer) */
static const double FACTORIAL[DFWB_HY_MAX_TERMS + 2] = {
    1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0, 5040.0, 40320.0, 362880.0, 3628800.0, 39916800.0, 479001600.0,
    6227020800.0, 87178291200.0, 1307674368000.0, 20922789888000.0, 355687428096000.0, 6402373705728000.0,
    1.21645100408832e+17, 2.43290200817664e+18, 5.109094217170944e+19, 1.1240007277776077e+21,
    2.585201673888498e+22, 6.204484017332394e+23, 1.5511210043330986e+25, 4.0329146112660565e+26,
    1.0888869450418352e+28, 3.0488834461171387e+29, 8.841761993739702e+30, 2.6525285981219107e+32,
    8.222838654177922e+33, 2.631308369336935e+35, 8.683317618811886e+36, 2.9523279903960416e+38,
    1.0333147966386145e+40, 3.7199332678990125e+41, 1.3763753091226346e+43, 5.230226174666011e+44,
    2.0397882081197444e+46, 8.159152832478977e+47, 3.345252661316381e+49};

/* _dot: sum(x * y for x, y in zip(a, b)) */
static double dot(const double *a, const double *b, int n)
{
    double s = 0.0;
    int i;
    for (i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* _dot(|a|, |b|) */
static double dot_abs(const double *a, const double *b, int n)
{
    double s = 0.0;
    int i;
    for (i = 0; i < n; i++)
        s += fabs(a[i]) * fabs(b[i]);
    return s;
}

static const char *kind_name(int kind)
{
    if (kind == DFWB_HY_SECTION_UP)
        return "section+";
    if (kind == DFWB_HY_SECTION_DOWN)
        return "section-";
    return dfwb_event_name(kind);
}

/* The current piece's mode (built: begin builds it). */
static dfwb_hy_mode *current(const dfwb_hy *hy) { return hy->modes[DFWB_HY_SLOT(hy, hy->key)]; }

static int is_section(int kind) { return kind == DFWB_HY_SECTION_UP || kind == DFWB_HY_SECTION_DOWN; }

/* -- Mode ---------------------------------------------------------------------------------------- */
/* balance(A): powers of two d_i such that D^-1 A D has rows and columns of like size (at most 60 sweeps). */
static void balance(const dfwb_hy_mode *m, double *d)
{
    const int n = m->n;
    int sweep, i, j, changed;
    for (i = 0; i < n; i++)
        d[i] = 1.0;
    for (sweep = 0; sweep < 60; sweep++) {
        changed = 0;
        for (i = 0; i < n; i++) {
            double col = 0.0, row = 0.0, f = 1.0;
            for (j = 0; j < n; j++)
                if (j != i)
                    col += fabs(m->A[j][i]) * d[i] / d[j];
            for (j = 0; j < n; j++)
                if (j != i)
                    row += fabs(m->A[i][j]) * d[j] / d[i];
            if (col == 0.0 || row == 0.0)
                continue;
            while (col < row / 2.0 && f < 1073741824.0) {
                col = col * 2.0;
                row = row / 2.0;
                f = f * 2.0;
            }
            while (col > row * 2.0 && f > 0x1p-30) {
                col = col / 2.0;
                row = row * 2.0;
                f = f / 2.0;
            }
            if (f != 1.0 && (col + row) < 0.95 * (col / f + row * f)) {
                d[i] *= f;
                changed = 1;
            }
        }
        if (!changed)
            break;
    }
}

/* nilpotency: 1 where A = 0, 2 where A != 0 and every product A_iq A_qj has a zero factor, else 0. */
static int nilpotency(const dfwb_hy_mode *m)
{
    int i, j, q, zero = 1;
    for (i = 0; i < m->n; i++)
        for (j = 0; j < m->n; j++)
            zero &= m->A[i][j] == 0.0;
    if (zero)
        return 1;
    for (i = 0; i < m->n; i++)
        for (q = 0; q < m->n; q++)
            for (j = 0; j < m->n; j++)
                if (m->A[i][q] != 0.0 && m->A[q][j] != 0.0)
                    return 0;
    return 2;
}

/* Mode.__init__ after system(key) filled n, A, c and the system's events (the section's are added here). */
static int build_mode(dfwb_hy *hy, int key, dfwb_hy_mode *m, dfwb_err *err)
{
    double d[DFWB_HY_DIM], P[DFWB_HY_DIM][DFWB_HY_DIM], AP[DFWB_HY_DIM][DFWB_HY_DIM];
    double r[DFWB_HY_DIM], ra[DFWB_HY_DIM], r2[DFWB_HY_DIM], ra2[DFWB_HY_DIM];
    double rho = 0.0, term;
    int n, i, j, k, e, rc, index;
    memset(m, 0, sizeof *m);
    m->key = key;
    rc = hy->system(hy, key, m, err);
    if (rc != DFWB_OK)
        return rc;
    if (hy->has_section) { /* (SECTION_UP, [-v for v in L], -l0), (SECTION_DOWN, list(L), l0) */
        dfwb_hy_event *up = &m->ev[m->nev], *down = &m->ev[m->nev + 1];
        up->kind = DFWB_HY_SECTION_UP;
        down->kind = DFWB_HY_SECTION_DOWN;
        for (j = 0; j < DFWB_HY_DIM; j++) {
            up->L[j] = -hy->section_L[j];
            down->L[j] = hy->section_L[j];
        }
        up->l0 = -hy->section_l0;
        down->l0 = hy->section_l0;
        m->nev += 2;
    }
    n = m->n;
    if (m->integrated) { /* IntegratedMode.__init__: the linear part's time scale, the largest step */
        for (i = 0; i < n; i++) {
            double s = 0.0;
            for (j = 0; j < n; j++)
                s += fabs(m->A[i][j]);
            if (i == 0 || s > rho)
                rho = s;
        }
        m->resolution = rho > 0.0 ? 1.0 / rho : 1.0;
        m->max_step = m->h = 4.0 * m->resolution;
        m->terms = 2; /* its trend's coefficients: g, g', g''/2 */
        dfwb_in_setup();
        return DFWB_OK;
    }
    balance(m, d);
    for (i = 0; i < n; i++) { /* rho = max(sum(|A_ij| d_j / d_i)) */
        double s = 0.0;
        for (j = 0; j < n; j++)
            s += fabs(m->A[i][j]) * d[j] / d[i];
        if (i == 0 || s > rho)
            rho = s;
    }
    for (i = 0; i < n; i++)
        m->scale[i] = d[i];
    m->resolution = rho > 0.0 ? TAYLOR_RADIUS / rho : 1.0;
    /* a chunk of at most NILPOTENT_CHUNK: rho h <= 1 still, and h^k stays finite (a mass of 1e300 kg) */
    m->h = m->resolution < DFWB_HY_NILPOTENT_CHUNK ? m->resolution : DFWB_HY_NILPOTENT_CHUNK;
    m->terms = 1;
    term = 1.0;
    while (rho > 0.0 && m->terms < DFWB_HY_MAX_TERMS && term > TAYLOR_TOLERANCE) {
        m->terms += 1;
        term *= TAYLOR_RADIUS / (double)m->terms;
    }
    index = nilpotency(m);
    if (index) { /* A^index = 0: the series ends after index terms, exact on any chunk */
        m->h = DFWB_HY_NILPOTENT_CHUNK;
        m->terms = index;
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            m->absA[i][j] = fabs(m->A[i][j]);
    /* Psi by Horner: h (I + A h/2 (I + A h/3 (...))) */
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            P[i][j] = i == j ? 1.0 : 0.0;
    for (k = m->terms; k > 1; k--) {
        for (i = 0; i < n; i++)
            for (j = 0; j < n; j++) {
                double s = 0.0;
                int q;
                for (q = 0; q < n; q++)
                    s += m->A[i][q] * P[q][j];
                AP[i][j] = s;
            }
        for (i = 0; i < n; i++)
            for (j = 0; j < n; j++)
                P[i][j] = (i == j ? 1.0 : 0.0) + AP[i][j] * m->h / (double)k;
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            m->psi[i][j] = P[i][j] * m->h;
    for (e = 0; e < m->nev; e++) {
        const double *L = m->ev[e].L;
        for (j = 0; j < n; j++) {
            r[j] = L[j];
            ra[j] = fabs(L[j]);
        }
        for (k = 1; k <= m->terms; k++) {
            for (j = 0; j < n; j++) {
                m->rows[e][k - 1][j] = r[j] / FACTORIAL[k];
                m->abs_rows[e][k - 1][j] = ra[j] / FACTORIAL[k];
            }
            for (j = 0; j < n; j++) {
                double s = 0.0, sa = 0.0;
                int q;
                for (q = 0; q < n; q++)
                    s += r[q] * m->A[q][j];
                for (q = 0; q < n; q++)
                    sa += ra[q] * m->absA[q][j];
                r2[j] = s;
                ra2[j] = sa;
            }
            memcpy(r, r2, sizeof r);
            memcpy(ra, ra2, sizeof ra);
        }
        /* reach: sum(row[j] * h ** k for k, row in enumerate(abs_rows, start=1)) */
        for (j = 0; j < n; j++) {
            double s = 0.0;
            for (k = 1; k <= m->terms; k++)
                s += m->abs_rows[e][k - 1][j] * dfwb_pow(m->h, (double)k, err);
            m->reach[e][j] = s;
        }
        {
            double s = 0.0;
            for (j = 0; j < n; j++)
                s += fabs(L[j]) * d[j];
            m->norms[e] = s;
        }
        if (err->overflow != NULL) /* Python raised OverflowError at the power */
            return DFWB_E_MATH;
    }
    m->tail = index ? 0.0 : 2.0 * m->h / FACTORIAL[m->terms + 1];
    m->curvature_tail = index || m->terms == 1 ? 0.0 : 2.0 * rho / FACTORIAL[m->terms - 1];
    return DFWB_OK;
}

/* Mode.balanced_size: |D^-1 X'|_inf */
static double balanced_size(const dfwb_hy_mode *m, const double *dX)
{
    double size = 0.0;
    int i;
    for (i = 0; i < m->n; i++) {
        const double v = fabs(dX[i]) / m->scale[i];
        if (i == 0 || v > size)
            size = v;
    }
    return size;
}

/* Mode.cannot_fire: event function ``index`` provably stays positive over the chunk from X. */
static int cannot_fire(const dfwb_hy_mode *m, int index, const double *X, const double *dX, double size)
{
    const dfwb_hy_event *ev = &m->ev[index];
    const double g = dot(ev->L, X, m->n) + ev->l0;
    double change, rounding;
    if (g <= 0.0)
        return 0;
    change = dot_abs(m->reach[index], dX, m->n) + m->norms[index] * size * m->tail; /* reach >= 0 */
    rounding = TREND_ROUNDING * (dot_abs(ev->L, X, m->n) + fabs(ev->l0));
    return g > 1.001 * change + rounding;
}

/* Mode.derivative (IntegratedMode's: plus its nonlinear term) */
static void derivative(const dfwb_hy *hy, const dfwb_hy_mode *m, const double *X, double *dX)
{
    int i;
    for (i = 0; i < m->n; i++)
        dX[i] = dot(m->A[i], X, m->n) + m->c[i];
    if (m->integrated)
        dX[m->row] += hy->law(hy, m->sign, X[m->col]);
}

/* IntegratedMode.second: X'' at X (X' = dX) */
static void second(const dfwb_hy *hy, const dfwb_hy_mode *m, const double *X, const double *dX, double *d2)
{
    int i;
    for (i = 0; i < m->n; i++)
        d2[i] = dot(m->A[i], dX, m->n);
    d2[m->row] += hy->law_slope(hy, m->sign, X[m->col]) * dX[m->col];
}

/* Mode.state: X(a + tau) from X(a) and X'(a) by the Taylor series (Horner). */
static void mode_state(const dfwb_hy_mode *m, const double *X, const double *dX, double tau, double *out)
{
    double krylov[DFWB_HY_MAX_TERMS][DFWB_HY_DIM], acc[DFWB_HY_DIM];
    const int n = m->n;
    int i, k;
    for (i = 0; i < n; i++)
        krylov[0][i] = dX[i];
    for (k = 1; k < m->terms; k++)
        for (i = 0; i < n; i++)
            krylov[k][i] = dot(m->A[i], krylov[k - 1], n);
    for (i = 0; i < n; i++)
        acc[i] = krylov[m->terms - 1][i];
    for (k = m->terms - 1; k > 0; k--) {
        const double f = tau / (double)(k + 1);
        for (i = 0; i < n; i++)
            acc[i] = krylov[k - 1][i] + f * acc[i];
    }
    for (i = 0; i < n; i++)
        out[i] = X[i] + tau * acc[i];
}

/* Mode.step: X(a + h) */
static void mode_step(const dfwb_hy_mode *m, const double *X, const double *dX, double *out)
{
    int i;
    for (i = 0; i < m->n; i++)
        out[i] = X[i] + dot(m->psi[i], dX, m->n);
}

/* Mode.coefficients: the Taylor coefficients of event function ``index`` at X and their rounding scales
 * (terms + 1 of each). */
static void coefficients(const dfwb_hy *hy, const dfwb_hy_mode *m, int index, const double *X, const double *dX,
                         double dt, double *coeffs, double *scales)
{
    const dfwb_hy_event *ev = &m->ev[index];
    const int n = m->n;
    double size[DFWB_HY_DIM], absX[DFWB_HY_DIM];
    int i, k;
    if (m->integrated) { /* IntegratedMode.coefficients: [g, g', g''/2] and their scales */
        double d2[DFWB_HY_DIM];
        second(hy, m, X, dX, d2);
        coeffs[0] = dot(ev->L, X, n) + ev->l0;
        coeffs[1] = dot(ev->L, dX, n);
        coeffs[2] = 0.5 * dot(ev->L, d2, n);
        scales[0] = dot_abs(ev->L, X, n) + fabs(ev->l0);
        scales[1] = dot_abs(ev->L, dX, n);
        scales[2] = 0.5 * dot_abs(ev->L, d2, n);
        if (dt != 0.0) {
            const double shift = dt / TREND_ROUNDING;
            for (k = 0; k < 2; k++)
                scales[k] += (double)(k + 1) * fabs(coeffs[k + 1]) * shift;
        }
        return;
    }
    coeffs[0] = dot(ev->L, X, n) + ev->l0;
    for (k = 1; k <= m->terms; k++)
        coeffs[k] = dot(m->rows[index][k - 1], dX, n);
    for (i = 0; i < n; i++)
        absX[i] = fabs(X[i]);
    for (i = 0; i < n; i++)
        size[i] = fabs(dot(m->absA[i], absX, n));
    for (i = 0; i < n; i++)
        size[i] = size[i] + fabs(m->c[i]);
    scales[0] = dot_abs(ev->L, X, n) + fabs(ev->l0);
    for (k = 1; k <= m->terms; k++)
        scales[k] = dot(m->abs_rows[index][k - 1], size, n);
    if (dt != 0.0) { /* Python: `if dt:` (NaN is true) */
        const double shift = dt / TREND_ROUNDING;
        for (k = 0; k < m->terms; k++)
            scales[k] += (double)(k + 1) * fabs(coeffs[k + 1]) * shift;
    }
}

/* trend: the sign just after a point from its Taylor coefficients (0: zero within rounding) */
static int trend(const double *coeffs, const double *scales, int len)
{
    int i;
    for (i = 0; i < len; i++)
        if (fabs(coeffs[i]) > TREND_ROUNDING * scales[i])
            return coeffs[i] > 0.0 ? 1 : -1;
    return 0;
}

/* -- Polynomial ---------------------------------------------------------------------------------- */
typedef struct {
    const double *c;
    int n;
} poly;

static void poly_fun(const void *ctx, double tau, double *g, double *dg)
{
    const poly *P = (const poly *)ctx;
    double p = 0.0, dp = 0.0;
    int i;
    for (i = P->n - 1; i >= 0; i--) {
        dp = dp * tau + p;
        p = p * tau + P->c[i];
    }
    *g = p;
    *dg = dp;
}

/* Polynomial.curvature_bound: a bound on |p''| over [0, h], plus tail */
static double curvature_bound(const poly *P, double h, double tail, dfwb_err *err)
{
    double total = 0.0;
    int i;
    for (i = 2; i < P->n; i++)
        total += (double)(i * (i - 1)) * fabs(P->c[i]) * dfwb_pow(h, (double)(i - 2), err);
    return 1.0001 * total + tail + 1e-300;
}

/* -- HybridSolver ------------------------------------------------------------------------------ */
void dfwb_hy_init(dfwb_hy *hy, int n, dfwb_hy_system_fn system, dfwb_hy_fire_fn fire, const double *section_L,
                  double section_l0)
{
    int j;
    hy->system = system;
    hy->fire = fire;
    hy->n = n;
    hy->t = 0.0;
    hy->events = 0;
    hy->stopped = 0;
    for (j = 0; j < DFWB_HY_MODES; j++)
        hy->modes[j] = NULL;
    hy->variant = 0;
    hy->has_section = section_L != NULL;
    for (j = 0; j < DFWB_HY_DIM; j++)
        hy->section_L[j] = section_L != NULL && j < n ? section_L[j] : 0.0;
    hy->section_l0 = section_l0;
    hy->watching = 0;
    hy->time_rounding = 0.0;
    hy->key = 0;
    hy->ndeparting = 0;
    hy->first = hy->searched = hy->has_event = 0;
    hy->crossings = NULL;
    hy->ncrossings = hy->crossings_cap = 0;
    hy->crossings_dropped = 0;
    hy->stack.data = NULL;
    hy->stack.cap = 0;
    memset(&hy->log, 0, sizeof hy->log);
}

dfwb_hy_mode *dfwb_hy_mode_of(dfwb_hy *hy, int key, dfwb_err *err)
{
    dfwb_hy_mode *m;
    int rc;
    if (key < 0 || key >= DFWB_HY_KEYS || hy->variant < 0 || hy->variant >= DFWB_HY_VARIANTS) {
        dfwb_fail(err, DFWB_E_ARGUMENT, "no mode %d (variant %d)", key, hy->variant);
        return NULL;
    }
    if (hy->modes[DFWB_HY_SLOT(hy, key)] != NULL)
        return hy->modes[DFWB_HY_SLOT(hy, key)];
    m = (dfwb_hy_mode *)malloc(sizeof *m);
    if (m == NULL) {
        dfwb_fail(err, DFWB_E_MEMORY, "out of memory (a mode of the loop)");
        return NULL;
    }
    rc = build_mode(hy, key, m, err);
    if (rc != DFWB_OK) {
        free(m); /* an overflow (DFWB_E_MATH, err->code still DFWB_OK) is reported by dfwb_err_finish */
        return NULL;
    }
    hy->modes[DFWB_HY_SLOT(hy, key)] = m;
    return m;
}

int dfwb_hy_after(dfwb_hy *hy, int key, int index, const double *X, int *sign, dfwb_err *err)
{
    double dX[DFWB_HY_DIM], coeffs[DFWB_HY_MAX_TERMS + 1], scales[DFWB_HY_MAX_TERMS + 1];
    const dfwb_hy_mode *m = dfwb_hy_mode_of(hy, key, err);
    if (m == NULL)
        return err->code != DFWB_OK ? err->code : DFWB_E_MATH;
    derivative(hy, m, X, dX);
    coefficients(hy, m, index, X, dX, hy->time_rounding, coeffs, scales);
    *sign = trend(coeffs, scales, m->terms + 1);
    return DFWB_OK;
}

/* Python's list repr of a state: [x, y, ...] */
static void state_repr(const double *X, int n, char *out, size_t len)
{
    char r[DFWB_REPR_SIZE];
    size_t pos = 0;
    int i;
    out[0] = '\0';
    if (len < 3)
        return;
    out[pos++] = '[';
    for (i = 0; i < n; i++) {
        size_t k;
        dfwb_repr(X[i], r);
        if (i > 0 && pos + 2 < len) {
            out[pos++] = ',';
            out[pos++] = ' ';
        }
        for (k = 0; r[k] != '\0' && pos + 2 < len; k++)
            out[pos++] = r[k];
    }
    out[pos++] = ']';
    out[pos] = '\0';
}

/* -- IntegratedMode: a chunk is one DOPRI5 step ------------------------------------------------------------ */
/* IntegratedMode.gross: the size of the terms summed into X' */
static void gross_of(const dfwb_hy *hy, const dfwb_hy_mode *m, const double *X, double *gross)
{
    int i, j;
    for (i = 0; i < m->n; i++) { /* sum(abs(a * x) for a, x in zip(row, X)) + abs(ci) */
        double sum = 0.0;
        for (j = 0; j < m->n; j++)
            sum += fabs(m->A[i][j] * X[j]);
        gross[i] = sum + fabs(m->c[i]);
    }
    gross[m->row] += fabs(hy->law(hy, m->sign, X[m->col]));
}

/* IntegratedMode.take: one accepted step from (a, X0 = hy->X, dX0 = hy->dX) with trial size h, into the chunk's
 * step fields (peak: the piece's peaks so far, may be hy->peak) */
/* take's attempt: the stages of one step of size h from (hy->X, hy->dX), and its error ratio */
typedef struct {
    const dfwb_hy *hy;
    const dfwb_hy_mode *m;
    const double *peak, *gross, *moved;
    double stages[7][DFWB_HY_DIM], ks[7][DFWB_HY_DIM];
} step_try;

static double attempt_step(void *ctx, double h)
{
    step_try *s = (step_try *)ctx;
    const dfwb_hy *hy = s->hy;
    const int n = s->m->n;
    const double *X0 = hy->X;
    double ratio = 0.0;
    int i, j, q;
    memcpy(s->stages[0], X0, (size_t)n * sizeof *X0);
    memcpy(s->ks[0], hy->dX, (size_t)n * sizeof *X0);
    for (i = 1; i < 7; i++) {
        for (j = 0; j < n; j++) {
            double sum = 0.0;
            for (q = 0; q < i; q++)
                sum += dfwb_in_a[i][q] * s->ks[q][j];
            s->stages[i][j] = X0[j] + h * sum;
        }
        derivative(hy, s->m, s->stages[i], s->ks[i]);
    }
    for (j = 0; j < n; j++) { /* ratio = max(ratio, _ratio(err, scale)) */
        double sum = 0.0, scale, value;
        for (q = 0; q < 7; q++)
            sum += dfwb_in_e[q] * s->ks[q][j];
        scale = hy->rtol * dfwb_in_max3(s->peak[j], fabs(X0[j]), fabs(s->stages[6][j]))
                + DFWB_IN_ROUNDING * h * (s->gross[j] + h * s->moved[j]);
        value = dfwb_in_ratio(h * sum, scale);
        if (value > ratio)
            ratio = value;
    }
    return ratio;
}

static int take(dfwb_hy *hy, const dfwb_hy_mode *m, double a, double h, const double *peak, dfwb_err *err)
{
    const int n = m->n;
    const double *X0 = hy->X, *dX0 = hy->dX;
    double gross[DFWB_HY_DIM], moved[DFWB_HY_DIM], factor, new_peak[DFWB_HY_DIM];
    double (*stages)[DFWB_HY_DIM], (*ks)[DFWB_HY_DIM];
    int i, j, rc;
    step_try s;
    h = dfwb_in_min3(h, m->max_step, dfwb_in_feature_step(m->feature, X0[m->col], dX0[m->col]));
    gross_of(hy, m, X0, gross);
    for (i = 0; i < n; i++) { /* moved: sum(abs(a) * g for a, g in zip(row, gross)) */
        double sum = 0.0;
        for (j = 0; j < n; j++)
            sum += fabs(m->A[i][j]) * gross[j];
        moved[i] = sum;
    }
    s.hy = hy;
    s.m = m;
    s.peak = peak;
    s.gross = gross;
    s.moved = moved;
    rc = dfwb_in_control(attempt_step, &s, a, &h, &factor, "loop cannot resolve its motion",
                         "a stiff or singular mode", err);
    if (rc != DFWB_OK)
        return rc;
    stages = s.stages;
    ks = s.ks;
    for (j = 0; j < n; j++)
        new_peak[j] = fabs(stages[6][j]) > peak[j] ? fabs(stages[6][j]) : peak[j];
    hy->step_h = h;
    memcpy(hy->X1, stages[6], (size_t)n * sizeof *X0);
    memcpy(hy->dX1, ks[6], (size_t)n * sizeof *X0);
    second(hy, m, X0, dX0, hy->d20);
    second(hy, m, hy->X1, hy->dX1, hy->d21);
    hy->next_h = h * factor;
    memcpy(hy->peak, new_peak, (size_t)n * sizeof *X0);
    return DFWB_OK;
}

/* IntegratedMode.state: X at a + tau within the step (each component's quintic Hermite) */
static void integrated_state(const dfwb_hy *hy, double tau, double *out)
{
    const double h = hy->step_h;
    double theta;
    int i;
    if (tau == h) {
        memcpy(out, hy->X1, (size_t)hy->n * sizeof *out);
        return;
    }
    theta = tau / h;
    for (i = 0; i < hy->n; i++) {
        double c[5];
        c[0] = hy->X1[i] - hy->X[i];
        c[1] = h * hy->dX[i];
        c[2] = h * h * hy->d20[i];
        c[3] = h * hy->dX1[i];
        c[4] = h * h * hy->d21[i];
        out[i] = dfwb_in_quintic(hy->X[i], c, theta);
    }
}

typedef struct {
    const dfwb_hy *hy;
    const dfwb_hy_event *ev;
} event_ctx;

/* g(theta) of IntegratedMode.search: the event function at a + theta h */
static double event_fun(const void *ctx, double theta)
{
    const event_ctx *c = (const event_ctx *)ctx;
    double X[DFWB_HY_DIM];
    integrated_state(c->hy, theta * c->hy->step_h, X);
    return dot(c->ev->L, X, c->hy->n) + c->ev->l0;
}

/* IntegratedMode.search: the first event within the step (sampled 8 times, refined by Illinois) */
static void integrated_search(const dfwb_hy *hy, const dfwb_hy_mode *m, int *found, double *best_tau,
                              int *best_kind)
{
    const double h = hy->step_h;
    double gross[DFWB_HY_DIM];
    int index, i;
    *found = 0;
    gross_of(hy, m, hy->X, gross);
    for (index = 0; index < m->nev; index++) {
        const int kind = m->ev[index].kind;
        int departing = 0;
        double floor_g, theta;
        event_ctx ctx;
        if (is_section(kind) && kind != hy->watching)
            continue;
        floor_g = DFWB_IN_ROUNDING * h * dot_abs(m->ev[index].L, gross, m->n);
        if (hy->first)
            for (i = 0; i < hy->ndeparting; i++)
                departing |= hy->departing[i] == index;
        ctx.hy = hy;
        ctx.ev = &m->ev[index];
        if (dfwb_in_stop(event_fun, &ctx, event_fun(&ctx, 0.0), floor_g, *found ? *best_tau / h : 1.0, !departing,
                         &theta) && (!*found || h * theta < *best_tau)) {
            *found = 1;
            *best_tau = h * theta;
            *best_kind = kind;
        }
    }
}

/* _chunk_start */
static int chunk_start(dfwb_hy *hy, double t, const double *X, int first, dfwb_err *err)
{
    const dfwb_hy_mode *m = current(hy);
    int i;
    for (i = 0; i < hy->n; i++)
        if (!(fabs(X[i]) <= DFWB_HY_MAX_STATE)) {
            char rt[DFWB_REPR_SIZE], rx[DFWB_HY_DIM * (DFWB_REPR_SIZE + 2) + 4];
            dfwb_repr(t, rt);
            state_repr(X, hy->n, rx, sizeof rx);
            return dfwb_fail(err, DFWB_E_DIVERGED, "the state is beyond [-1e+150, 1e+150] at t = %s s (%s): the "
                             "loop diverges (or its initial values are too large)", rt, rx);
        }
    hy->a = t;
    if (X != hy->X)
        memmove(hy->X, X, (size_t)hy->n * sizeof *X);
    derivative(hy, m, hy->X, hy->dX);
    if (m->integrated) { /* one accepted step, sized by the error control from the piece's start */
        double peak[DFWB_HY_DIM];
        int rc;
        if (first)
            for (i = 0; i < hy->n; i++)
                peak[i] = fabs(hy->X[i]);
        else
            memcpy(peak, hy->peak, sizeof peak);
        rc = take(hy, m, t, first ? m->max_step / 64.0 : hy->next_h, peak, err);
        if (rc != DFWB_OK)
            return rc;
        hy->b = t + hy->step_h;
    } else {
        hy->step_h = hy->next_h = 0.0; /* canonical: a closed-form chunk holds no step */
        memset(hy->X1, 0, sizeof hy->X1);
        memset(hy->dX1, 0, sizeof hy->dX1);
        memset(hy->d20, 0, sizeof hy->d20);
        memset(hy->d21, 0, sizeof hy->d21);
        memset(hy->peak, 0, sizeof hy->peak);
        hy->b = t + m->h;
    }
    hy->first = first;
    hy->has_event = 0;
    hy->searched = 0;
    return DFWB_OK;
}

/* _begin */
static int begin(dfwb_hy *hy, double t, const double *X, int key, int ndeparting, const int *departing,
                 dfwb_err *err)
{
    int i;
    hy->key = key;
    if (dfwb_hy_mode_of(hy, key, err) == NULL)
        return err->code != DFWB_OK ? err->code : DFWB_E_MATH;
    hy->ndeparting = ndeparting;
    for (i = 0; i < ndeparting; i++)
        hy->departing[i] = departing[i];
    return chunk_start(hy, t, X, 1, err);
}

int dfwb_hy_start(dfwb_hy *hy, double t0, const double *X0, int key, int departing, dfwb_err *err)
{
    int deps[2], ndeps = 0;
    hy->t = t0;
    hy->time_rounding = 4.0 * DFWB_EPS * fabs(t0);
    if (departing >= 0)
        deps[ndeps++] = departing;
    if (hy->has_section) {
        double dX[DFWB_HY_DIM], coeffs[DFWB_HY_MAX_TERMS + 1], scales[DFWB_HY_MAX_TERMS + 1];
        const dfwb_hy_mode *m = dfwb_hy_mode_of(hy, key, err);
        int up;
        if (m == NULL)
            return err->code != DFWB_OK ? err->code : DFWB_E_MATH;
        up = m->nev - 2;
        derivative(hy, m, X0, dX);
        coefficients(hy, m, up, X0, dX, 0.0, coeffs, scales);
        hy->watching = trend(coeffs, scales, m->terms + 1) > 0 ? DFWB_HY_SECTION_UP : DFWB_HY_SECTION_DOWN;
        if (fabs(coeffs[0]) <= TREND_ROUNDING * scales[0])
            deps[ndeps++] = hy->watching == DFWB_HY_SECTION_UP ? up : up + 1;
    }
    return begin(hy, t0, X0, key, ndeps, deps, err);
}

/* _search: the first event in the current chunk (*found, *tau, *kind). */
static int search(dfwb_hy *hy, int *found, double *best_tau, int *best_kind, dfwb_err *err)
{
    const dfwb_hy_mode *m = current(hy);
    const double *X = hy->X, *dX = hy->dX;
    const double h = m->h, size = balanced_size(m, dX), dt = hy->first ? hy->time_rounding : 0.0;
    double coeffs[DFWB_HY_MAX_TERMS + 1], scales[DFWB_HY_MAX_TERMS + 1];
    int index, i;
    *found = 0;
    if (m->integrated) {
        integrated_search(hy, m, found, best_tau, best_kind);
        return DFWB_OK;
    }
    for (index = 0; index < m->nev; index++) {
        const int kind = m->ev[index].kind;
        int departing = 0, j = 0, len = m->terms + 1, has_root, rc;
        double limit, tail, K, tau;
        poly p;
        dfwb_err local;
        char message[512];
        if (is_section(kind) && kind != hy->watching)
            continue;
        if (hy->first)
            for (i = 0; i < hy->ndeparting; i++)
                departing |= hy->departing[i] == index;
        if (!departing && cannot_fire(m, index, X, dX, size))
            continue;
        coefficients(hy, m, index, X, dX, dt, coeffs, scales);
        if (departing || fabs(coeffs[0]) <= TREND_ROUNDING * scales[0]) {
            j = 1;
            while (j < len && fabs(coeffs[j]) <= TREND_ROUNDING * scales[j])
                j += 1;
            if (j == len)
                continue; /* identically zero within rounding: it stays on the boundary, not an event */
        }
        p.c = coeffs + j;
        p.n = len - j;
        limit = *found ? *best_tau : h;
        tail = m->norms[index] * size * m->curvature_tail / dfwb_pow(h, (double)j, err);
        K = curvature_bound(&p, limit, tail, err);
        if (err->overflow != NULL)
            return DFWB_E_MATH;
        dfwb_err_init(&local, message, sizeof message);
        rc = dfwb_first_root(poly_fun, NULL, &p, 0.0, limit, K, &hy->stack, &has_root, &tau, &local);
        if (rc == DFWB_E_LIMIT) {
            char ra[DFWB_REPR_SIZE], rb[DFWB_REPR_SIZE];
            dfwb_repr(hy->a, ra);
            dfwb_repr(hy->a + limit, rb);
            return dfwb_fail(err, DFWB_E_LIMIT, "the search for the event %s on [%s, %s] s needed more than the "
                             "bounded number of evaluations: the motion cannot be resolved at the loop's scale",
                             kind_name(kind), ra, rb);
        }
        if (rc != DFWB_OK)
            return dfwb_fail(err, rc, "%s", message);
        if (has_root && (!*found || tau < *best_tau)) {
            *found = 1;
            *best_tau = tau;
            *best_kind = kind;
        }
    }
    return DFWB_OK;
}

/* Python's f"{x:.{precision}g}", locale-proof */
static void format_g(double x, int precision, char *out, size_t len)
{
    char *c;
    snprintf(out, len, "%.*g", precision, x);
    for (c = out; *c != '\0'; c++)
        if (!((*c >= '0' && *c <= '9') || *c == 'e' || *c == '+' || *c == '-' || *c == 'i' || *c == 'n'
              || *c == 'f' || *c == 'a'))
            *c = '.';
}

static void add_crossing(dfwb_hy *hy, double t, const double *X)
{
    const size_t width = (size_t)hy->n + 1;
    if (hy->ncrossings == hy->crossings_cap) {
        size_t cap = hy->crossings_cap ? 2 * hy->crossings_cap : 16;
        double *data = cap < ((size_t)-1) / 2 / width / sizeof(double)
                           ? (double *)realloc(hy->crossings, cap * width * sizeof(double))
                           : NULL;
        if (data == NULL) { /* the record never changes the solution: counted as dropped */
            hy->crossings_dropped += 1;
            return;
        }
        hy->crossings = data;
        hy->crossings_cap = cap;
    }
    hy->crossings[hy->ncrossings * width] = t;
    memcpy(hy->crossings + hy->ncrossings * width + 1, X, (size_t)hy->n * sizeof *X);
    hy->ncrossings += 1;
}

int dfwb_hy_advance(dfwb_hy *hy, double t_end, int stop_section, const unsigned int *stop_events,
                    long long *budget_left, long long budget_total, dfwb_err *err)
{
    double fastest = 0.0, limit, fired = 0.0, chunks = 0.0;
    int i, have = 0, rc;
    hy->stopped = 0;
    if (!(isfinite(t_end) && t_end >= hy->t)) {
        char r[DFWB_REPR_SIZE], rt[DFWB_REPR_SIZE];
        dfwb_repr(t_end, r);
        dfwb_repr(hy->t, rt);
        return dfwb_fail(err, DFWB_E_VALUE, "t_end = %s is out of range: the end of a step must be a finite number "
                         ">= the current time %s", r, rt);
    }
    for (i = 0; i < DFWB_HY_MODES; i++) /* min(mode.resolution for mode in self._modes.values()) */
        if (hy->modes[i] != NULL && (!have || hy->modes[i]->resolution < fastest)) {
            fastest = hy->modes[i]->resolution;
            have = 1;
        }
    if (t_end > DFWB_HY_TIME_LIMIT * fastest) {
        char r[DFWB_REPR_SIZE], g[40];
        dfwb_repr(t_end, r);
        format_g(DFWB_HY_TIME_LIMIT * fastest, 6, g, sizeof g);
        return dfwb_fail(err, DFWB_E_VALUE, "t_end = %s s is out of range: at most %s s (" TIME_LIMIT_TEXT " chunks "
                         "of the fastest mode, where a float still resolves them)", r, g);
    }
    limit = (double)DFWB_HY_EVENTS_PER_CHUNK * (1.0 + (t_end - hy->t) / fastest);
    for (;;) {
        if (!hy->searched) {
            int found, kind = 0;
            double tau = 0.0;
            rc = search(hy, &found, &tau, &kind, err);
            if (rc != DFWB_OK)
                return rc;
            hy->has_event = found;
            hy->event_tau = tau;
            hy->event_kind = kind;
            hy->searched = 1;
        }
        if (hy->has_event && hy->a + hy->event_tau <= t_end) {
            const double tau = hy->event_tau;
            const int kind = hy->event_kind;
            double t, X[DFWB_HY_DIM];
            int key, departing, fired_from;
            fired += 1.0;
            if (fired > limit) {
                char r0[DFWB_REPR_SIZE], r1[DFWB_REPR_SIZE];
                dfwb_repr(hy->t, r0);
                dfwb_repr(hy->a + tau, r1);
                return dfwb_fail(err, DFWB_E_LIMIT, "more than " EVENTS_PER_CHUNK_TEXT " events per chunk between "
                                 "t = %s and %s s (last event: %s): the motion chatters below the solver's "
                                 "resolution", r0, r1, kind_name(kind));
            }
            if (fired > DFWB_MAX_EVENTS_PER_STEP) {
                char r0[DFWB_REPR_SIZE], r1[DFWB_REPR_SIZE];
                dfwb_repr(hy->t, r0);
                dfwb_repr(hy->a + tau, r1);
                return dfwb_fail(err, DFWB_E_LIMIT, "more than %d events in one step between t = %s and t = %s "
                                 "(last event: %s): take smaller steps", DFWB_MAX_EVENTS_PER_STEP, r0, r1,
                                 kind_name(kind));
            }
            t = hy->a + tau;
            if (current(hy)->integrated)
                integrated_state(hy, tau, X);
            else
                mode_state(current(hy), hy->X, hy->dX, tau, X);
            hy->time_rounding = 4.0 * DFWB_EPS * fabs(t);
            if (is_section(kind)) { /* not an event of the system: watch the other direction from here */
                const dfwb_hy_mode *m = current(hy);
                int index;
                if (kind == DFWB_HY_SECTION_UP)
                    add_crossing(hy, t, X);
                hy->watching = kind == DFWB_HY_SECTION_UP ? DFWB_HY_SECTION_DOWN : DFWB_HY_SECTION_UP;
                index = hy->watching == DFWB_HY_SECTION_UP ? m->nev - 2 : m->nev - 1;
                rc = begin(hy, t, X, hy->key, 1, &index, err);
                if (rc != DFWB_OK)
                    return rc;
                if (stop_section && kind == DFWB_HY_SECTION_UP) {
                    t_end = t;
                    break;
                }
                continue;
            }
            key = hy->key;
            fired_from = hy->key;
            departing = -1;
            rc = hy->fire(hy, t, kind, X, &key, &departing, err);
            if (rc != DFWB_OK)
                return rc;
            hy->events += 1;
            dfwb_log_add(&hy->log, t, kind);
            rc = begin(hy, t, X, key, departing >= 0 ? 1 : 0, &departing, err);
            if (rc != DFWB_OK)
                return rc;
            if (stop_events != NULL && kind > 0 && kind < 32 && ((stop_events[fired_from] >> kind) & 1u)) {
                hy->stopped = kind;
                t_end = t;
                break;
            }
            continue;
        }
        if (hy->b > t_end)
            break;
        chunks += 1.0;
        if (chunks > DFWB_HY_MAX_CHUNKS_PER_STEP) {
            char r0[DFWB_REPR_SIZE], rt[40], rh[40];
            dfwb_repr(hy->t, r0);
            format_g(hy->b, 6, rt, sizeof rt);
            format_g(current(hy)->integrated ? hy->step_h : current(hy)->h, 3, rh, sizeof rh);
            return dfwb_fail(err, DFWB_E_LIMIT, "more than %d chunks of integration in one step from t = %s (at "
                             "t = %s s a chunk is %s s): take smaller steps", DFWB_HY_MAX_CHUNKS_PER_STEP, r0, rt, rh);
        }
        if (budget_left != NULL) { /* Budget.spend */
            *budget_left -= 1;
            if (*budget_left < 0) {
                char rt[40], rh[40];
                format_g(hy->b, 6, rt, sizeof rt);
                format_g(current(hy)->integrated ? hy->step_h : current(hy)->h, 3, rh, sizeof rh);
                return dfwb_fail(err, DFWB_E_LIMIT, "the exact loop needed more than %lld chunks of integration (at "
                                 "t = %s s a chunk is %s s): this study's motions are too long for its work budget, or "
                                 "the fastest time scale too far below the motion's", budget_total, rt, rh);
            }
        }
        {
            double X[DFWB_HY_DIM];
            if (current(hy)->integrated)
                memcpy(X, hy->X1, sizeof X);
            else
                mode_step(current(hy), hy->X, hy->dX, X);
            rc = chunk_start(hy, hy->b, X, 0, err);
            if (rc != DFWB_OK)
                return rc;
        }
    }
    hy->t = t_end;
    return DFWB_OK;
}

void dfwb_hy_state(const dfwb_hy *hy, double *X)
{
    const double tau = hy->t - hy->a;
    if (tau == 0.0)
        memcpy(X, hy->X, (size_t)hy->n * sizeof *X);
    else if (current(hy)->integrated)
        integrated_state(hy, tau, X);
    else
        mode_state(current(hy), hy->X, hy->dX, tau, X);
}

int dfwb_hy_copy(dfwb_hy *dst, const dfwb_hy *src)
{
    int i, ok = 1;
    memcpy(dst, src, sizeof *dst);
    dst->stack.data = NULL;
    dst->stack.cap = 0;
    dst->crossings = NULL;
    dst->crossings_cap = 0;
    dst->ncrossings = 0;
    for (i = 0; i < DFWB_HY_MODES; i++) {
        dst->modes[i] = NULL;
        if (src->modes[i] != NULL) {
            dst->modes[i] = (dfwb_hy_mode *)malloc(sizeof *dst->modes[i]);
            if (dst->modes[i] == NULL)
                ok = 0;
            else
                memcpy(dst->modes[i], src->modes[i], sizeof *dst->modes[i]);
        }
    }
    if (ok && src->ncrossings > 0) {
        const size_t bytes = src->ncrossings * ((size_t)src->n + 1) * sizeof(double);
        dst->crossings = (double *)malloc(bytes);
        if (dst->crossings == NULL)
            ok = 0;
        else {
            memcpy(dst->crossings, src->crossings, bytes);
            dst->ncrossings = dst->crossings_cap = src->ncrossings;
        }
    }
    if (!dfwb_log_copy(&dst->log, &src->log))
        ok = 0;
    if (!ok)
        dfwb_hy_free(dst);
    return ok;
}

void dfwb_hy_free(dfwb_hy *hy)
{
    int i;
    for (i = 0; i < DFWB_HY_MODES; i++) {
        free(hy->modes[i]);
        hy->modes[i] = NULL;
    }
    free(hy->crossings);
    hy->crossings = NULL;
    hy->ncrossings = hy->crossings_cap = 0;
    dfwb_stack_free(&hy->stack);
    dfwb_log_free(&hy->log);
}

int dfwb_hy_resume(dfwb_hy *hy, dfwb_err *err)
{
    const dfwb_hy_mode *m = current(hy);
    double chunk;
    char name[32];
    int i, rc, kind_ok = 0;
    if (m == NULL)
        return dfwb_fail(err, DFWB_E_STATE, "the state's current mode is not one of its modes built");
    if ((rc = dfwb_state_check(err, "time rounding", hy->time_rounding, isfinite(hy->time_rounding)
                               && hy->time_rounding >= 0.0, "must be finite and >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "watching", hy->watching, hy->has_section
                                      ? hy->watching == DFWB_HY_SECTION_UP || hy->watching == DFWB_HY_SECTION_DOWN
                                      : hy->watching == 0, "must be a section's direction (0 without one)"))
               != DFWB_OK
        || (rc = dfwb_state_check_int(err, "departing count", hy->ndeparting, 0 <= hy->ndeparting
                                      && hy->ndeparting <= 2, "must be in 0..2")) != DFWB_OK)
        return rc;
    for (i = 0; i < 2; i++) {
        snprintf(name, sizeof name, "departing[%d]", i);
        if ((rc = dfwb_state_check_int(err, name, hy->departing[i], i < hy->ndeparting
                                       ? 0 <= hy->departing[i] && hy->departing[i] < m->nev
                                       : hy->departing[i] == 0, "must be an event function of the mode (0 unused)"))
            != DFWB_OK)
            return rc;
    }
    if (m->integrated) { /* the step: finite, of positive length (at most the mode's largest), peaks >= 0 */
        int ok = isfinite(hy->step_h) && hy->step_h > 0.0 && hy->step_h <= m->max_step && isfinite(hy->next_h)
                 && hy->next_h > 0.0;
        for (i = 0; ok && i < DFWB_HY_DIM; i++)
            ok = i < hy->n ? isfinite(hy->X1[i]) && isfinite(hy->dX1[i]) && isfinite(hy->d20[i])
                                 && isfinite(hy->d21[i]) && isfinite(hy->peak[i]) && hy->peak[i] >= 0.0
                           : hy->X1[i] == 0.0 && hy->dX1[i] == 0.0 && hy->d20[i] == 0.0 && hy->d21[i] == 0.0
                                 && hy->peak[i] == 0.0;
        if (!ok)
            return dfwb_fail(err, DFWB_E_STATE, "the state's integrated step is out of range: needs a length in (0, "
                             "the mode's largest step], finite values and peaks >= 0 (0 beyond the state's size)");
    } else {
        int ok = hy->step_h == 0.0 && hy->next_h == 0.0;
        for (i = 0; ok && i < DFWB_HY_DIM; i++)
            ok = hy->X1[i] == 0.0 && hy->dX1[i] == 0.0 && hy->d20[i] == 0.0 && hy->d21[i] == 0.0
                 && hy->peak[i] == 0.0;
        if (!ok)
            return dfwb_fail(err, DFWB_E_STATE, "the state's integrated step is out of range: must be zeros in a "
                             "closed-form mode");
    }
    chunk = m->integrated ? hy->step_h : m->h;
    if ((rc = dfwb_state_check(err, "chunk start", hy->a, isfinite(hy->a) && 0.0 <= hy->a && hy->a <= hy->t
                               && hy->t < hy->a + chunk, "must be in [0, t] with t < start + h of its mode"))
        != DFWB_OK)
        return rc;
    for (i = 0; i < DFWB_HY_DIM; i++) {
        snprintf(name, sizeof name, "X[%d]", i);
        if ((rc = dfwb_state_check(err, name, hy->X[i], i < hy->n ? isfinite(hy->X[i]) : hy->X[i] == 0.0,
                                   "must be finite (0 beyond the state's size)")) != DFWB_OK)
            return rc;
    }
    if ((rc = dfwb_state_check_int(err, "first", hy->first, hy->first == 0 || hy->first == 1, "must be 0 or 1"))
            != DFWB_OK
        || (rc = dfwb_state_check_int(err, "searched", hy->searched, hy->searched == 0 || hy->searched == 1,
                                      "must be 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "has_event", hy->has_event, hy->has_event == 0
                                      || (hy->has_event == 1 && hy->searched), "must be 0, or 1 once searched"))
               != DFWB_OK)
        return rc;
    for (i = 0; i < m->nev; i++)
        kind_ok |= m->ev[i].kind == hy->event_kind;
    if (hy->has_event) {
        if ((rc = dfwb_state_check(err, "event tau", hy->event_tau, isfinite(hy->event_tau) && hy->event_tau >= 0.0
                                   && hy->event_tau <= chunk, "must be in [0, h] of its mode")) != DFWB_OK
            || (rc = dfwb_state_check_int(err, "event kind", hy->event_kind, kind_ok,
                                          "must be an event of its mode")) != DFWB_OK)
            return rc;
    } else if ((rc = dfwb_state_check(err, "event tau", hy->event_tau, hy->event_tau == 0.0, "must be 0 without an "
                                      "event")) != DFWB_OK
               || (rc = dfwb_state_check_int(err, "event kind", hy->event_kind, hy->event_kind == 0,
                                             "must be 0 without an event")) != DFWB_OK)
        return rc;
    derivative(hy, m, hy->X, hy->dX);
    hy->b = hy->a + chunk;
    return DFWB_OK;
}
