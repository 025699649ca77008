/* loops.c - the three plants in feedback with a linear controller, as exact hybrid systems: a port of
 * fmus/loops.py (FeedbackLoop, FrictionLoop, BacklashLoop, StaticBacklashLoop) on the solver of hybrid.c.
 * The API is documented in dfwb_core.h.
 *
 *     f = -G(s) y,   G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an),   n = 1..8
 *
 * The controller is realised as fmus/linear_system.py's LinearSystem realises it (controllable canonical
 * form, state z); the loop's state is the plant's coordinates q followed by z, and each mode of the plant
 * makes the loop an affine system (FeedbackLoop.system couples the plant's part with the controller).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "hybrid.h"
#include "plant.h"

#define MAX_ORDER DFWB_LOOP_MAX_ORDER
#define MAX_PLANT 4

struct dfwb_loop {
    dfwb_hy hy; /* first: the hybrid solver */
    int plant;  /* DFWB_PLANT_* */
    int m, order, out;
    /* -G(s): (Ac, Bc, C, D) of LinearSystem with C and D negated; f = D y + C z as a row over the state */
    double Ac[MAX_ORDER][MAX_ORDER], Bc[MAX_ORDER], C[MAX_ORDER], D;
    double f_row[DFWB_HY_DIM];
    /* the plant's constants: friction {M, B, Fc, Fs}, backlash {M1, M2, h, eps, r2, tol_h}, static {M, k, h} */
    double par[6];
    double bc[MAX_ORDER + 1], ac[MAX_ORDER]; /* G's coefficients b0..bn, a1..an (0 beyond n) */
    double section;                            /* the section's level (0 without one) */
    long long count; /* sticks, impacts, engagements */
};

/* a plant mode: q' = P q + p + phi f, event functions Lq.q + Lf f + l0 */
typedef struct {
    double P[MAX_PLANT][MAX_PLANT], p[MAX_PLANT], phi[MAX_PLANT];
    int nev, kind[2];
    double Lq[2][MAX_PLANT], Lf[2], l0[2];
} plant_mode;

static void add_event(plant_mode *pm, int kind, double l1, double l2, double l3, double l4, double Lf, double l0)
{
    const int e = pm->nev++;
    pm->kind[e] = kind;
    pm->Lq[e][0] = l1;
    pm->Lq[e][1] = l2;
    pm->Lq[e][2] = l3;
    pm->Lq[e][3] = l4;
    pm->Lf[e] = Lf;
    pm->l0[e] = l0;
}

/* the sign s of a mode key (slide, contact or engaged; 0 for stick and free) */
static int key_sign(const dfwb_loop *L, int key)
{
    if (key == 0)
        return 0;
    if (L->plant == DFWB_PLANT_BACKLASH)
        return key == DFWB_LOOP_CONTACT_LOWER ? -1 : 1;
    return key == 1 ? 1 : -1; /* slide +1 / engaged +1 is key 1, -1 is key 2 */
}

/* FrictionLoop.plant_mode, BacklashLoop.plant_mode, StaticBacklashLoop.plant_mode */
static void plant_mode_of(const dfwb_loop *L, int key, plant_mode *pm)
{
    const int s = key_sign(L, key);
    memset(pm, 0, sizeof *pm);
    if (L->plant == DFWB_PLANT_FRICTION) {
        const double M = L->par[0], B = L->par[1], Fc = L->par[2], Fs = L->par[3];
        if (key == DFWB_LOOP_STICK) {
            add_event(pm, DFWB_EVENT_BREAK_UP, 0.0, 0.0, 0.0, 0.0, -1.0, Fs); /* Fs - f > 0 */
            add_event(pm, DFWB_EVENT_BREAK_DOWN, 0.0, 0.0, 0.0, 0.0, 1.0, Fs); /* f + Fs > 0 */
            return;
        }
        pm->P[0][1] = 1.0;
        pm->P[1][1] = -B / M;
        pm->p[1] = (double)(-s) * Fc / M;
        pm->phi[1] = 1.0 / M;
        add_event(pm, DFWB_EVENT_BAND, 0.0, (double)s, 0.0, 0.0, 0.0, 0.0); /* s v > 0 */
    } else if (L->plant == DFWB_PLANT_BACKLASH) {
        const double M1 = L->par[0], M2 = L->par[1], h = L->par[2];
        pm->P[0][1] = 1.0;
        if (key == DFWB_LOOP_FREE) {
            pm->P[2][3] = 1.0;
            pm->phi[3] = 1.0 / M2;
            add_event(pm, DFWB_EVENT_WALL_LOWER, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0); /* g > 0 */
            add_event(pm, DFWB_EVENT_WALL_UPPER, 0.0, 0.0, -1.0, 0.0, 0.0, h); /* h - g > 0 */
            return;
        }
        pm->phi[1] = 1.0 / (M1 + M2);
        add_event(pm, DFWB_EVENT_RELEASE, 0.0, 0.0, 0.0, 0.0, (double)s, 0.0); /* sigma f > 0: pressing */
    } else {
        const double M = L->par[0], k = L->par[1], half = 0.5 * L->par[2];
        pm->P[0][1] = 1.0;
        pm->phi[1] = 1.0 / M;
        if (key == DFWB_LOOP_FREE) {
            add_event(pm, DFWB_EVENT_ENGAGE_UP, -1.0, 0.0, 1.0 / k, 0.0, 0.0, half); /* y/k + h/2 - x > 0 */
            add_event(pm, DFWB_EVENT_ENGAGE_DOWN, 1.0, 0.0, -1.0 / k, 0.0, 0.0, half); /* x - y/k + h/2 > 0 */
            return;
        }
        pm->P[2][1] = k;
        add_event(pm, DFWB_EVENT_REVERSE, 0.0, (double)s, 0.0, 0.0, 0.0, 0.0); /* s v > 0 */
    }
}

/* FeedbackLoop.system: the loop's A, c and event functions of a mode */
static int loop_system(dfwb_hy *hy, int key, dfwb_hy_mode *mode, dfwb_err *err)
{
    const dfwb_loop *L = (const dfwb_loop *)(const void *)hy;
    const int m = L->m, n = L->order, size = m + n;
    plant_mode pm;
    int i, j, e;
    (void)err;
    plant_mode_of(L, key, &pm);
    mode->n = size;
    for (i = 0; i < m; i++) /* row = list(P[i]) + [0.0] * n; [value + phi[i] * fv ...] */
        for (j = 0; j < size; j++)
            mode->A[i][j] = (j < m ? pm.P[i][j] : 0.0) + pm.phi[i] * L->f_row[j];
    for (i = 0; i < n; i++) { /* row = [0.0] * m + list(Ac[i]); row[out] += Bc[i] */
        for (j = 0; j < size; j++)
            mode->A[m + i][j] = j < m ? 0.0 : L->Ac[i][j - m];
        mode->A[m + i][L->out] += L->Bc[i];
    }
    for (i = 0; i < size; i++)
        mode->c[i] = i < m ? pm.p[i] : 0.0;
    mode->nev = pm.nev;
    for (e = 0; e < pm.nev; e++) {
        mode->ev[e].kind = pm.kind[e];
        for (j = 0; j < size; j++)
            mode->ev[e].L[j] = (j < m ? pm.Lq[e][j] : 0.0) + pm.Lf[e] * L->f_row[j];
        mode->ev[e].l0 = pm.l0[e];
    }
    return DFWB_OK;
}

/* FeedbackLoop.force: f = D y + C z at X */
static double loop_force(const dfwb_loop *L, const double *X)
{
    double s = 0.0;
    int i;
    for (i = 0; i < L->order; i++)
        s += L->C[i] * X[L->m + i];
    return L->D * X[L->out] + s;
}

/* -- friction ------------------------------------------------------------------------------- */
/* FrictionLoop._rest: at v = 0, stick while -Fs <= f <= Fs, else slide in the direction of f */
static int friction_rest(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    int sign, rc;
    rc = dfwb_hy_after(&L->hy, DFWB_LOOP_STICK, 0, X, &sign, err);
    if (rc != DFWB_OK)
        return rc;
    if (sign < 0) {
        *key = DFWB_LOOP_SLIDE_UP;
        *departing = 0;
        return DFWB_OK;
    }
    rc = dfwb_hy_after(&L->hy, DFWB_LOOP_STICK, 1, X, &sign, err);
    if (rc != DFWB_OK)
        return rc;
    if (sign < 0) {
        *key = DFWB_LOOP_SLIDE_DOWN;
        *departing = 0;
        return DFWB_OK;
    }
    L->count += 1;
    *key = DFWB_LOOP_STICK;
    *departing = -1;
    return DFWB_OK;
}

/* -- two-mass backlash ------------------------------------------------------------------------ */
/* BacklashLoop._at_wall: at a wall after any impact, contact or a flight away from it */
static int backlash_at_wall(dfwb_loop *L, int sigma, double *X, int *key, int *departing, dfwb_err *err)
{
    const double M2 = L->par[1], h = L->par[2], r2 = L->par[4], tol_h = L->par[5];
    const int contact = sigma < 0 ? DFWB_LOOP_CONTACT_LOWER : DFWB_LOOP_CONTACT_UPPER;
    double w, f;
    int press, rc;
    X[2] = sigma < 0 ? 0.0 : h;
    w = X[3];
    rc = dfwb_hy_after(&L->hy, contact, 0, X, &press, err);
    if (rc != DFWB_OK)
        return rc;
    f = loop_force(L, X);
    if ((w == 0.0 && press >= 0) || (press > 0 && 0.5 * w * w * M2 <= tol_h * fabs(f))) {
        X[1] += r2 * w; /* both move with the centre of mass */
        X[3] = 0.0;
        *key = contact;
        *departing = -1;
        return DFWB_OK;
    }
    *key = DFWB_LOOP_FREE;
    *departing = sigma < 0 ? 0 : 1;
    return DFWB_OK;
}

/* -- static backlash -------------------------------------------------------------------------- */
/* StaticBacklashLoop._engage */
static int static_engage(dfwb_loop *L, int s, double *X, int count, int *key, int *departing, dfwb_err *err)
{
    const double k = L->par[1], h = L->par[2];
    int sign, rc;
    if (count) /* reached the edge: y takes up from x (within rounding of the edge already) */
        X[2] = k * (X[0] - (double)s * 0.5 * h);
    rc = dfwb_hy_after(&L->hy, s > 0 ? DFWB_LOOP_ENGAGED_UP : DFWB_LOOP_ENGAGED_DOWN, 0, X, &sign, err);
    if (rc != DFWB_OK)
        return rc;
    if (sign > 0) {
        L->count += count;
        *key = s > 0 ? DFWB_LOOP_ENGAGED_UP : DFWB_LOOP_ENGAGED_DOWN;
        *departing = -1;
        return DFWB_OK;
    }
    *key = DFWB_LOOP_FREE;
    *departing = s > 0 ? 0 : 1;
    return DFWB_OK;
}

/* -- the switching logic: initial (t = 0) and _fire ----------------------------------------------- */
static int loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    *departing = -1;
    if (L->plant == DFWB_PLANT_FRICTION) {
        const double v = X[1];
        if (v != 0.0) {
            *key = v > 0.0 ? DFWB_LOOP_SLIDE_UP : DFWB_LOOP_SLIDE_DOWN;
            return DFWB_OK;
        }
        return friction_rest(L, X, key, departing, err);
    }
    if (L->plant == DFWB_PLANT_BACKLASH) {
        if (0.0 < X[2] && X[2] < L->par[2]) {
            *key = DFWB_LOOP_FREE;
            return DFWB_OK;
        }
        return backlash_at_wall(L, X[2] <= 0.0 ? -1 : 1, X, key, departing, err);
    }
    {
        const double k = L->par[1], h = L->par[2], play = X[0] - X[2] / k;
        int s;
        for (s = 1; s >= -1; s -= 2) /* on an edge: engaged if moving on */
            if ((double)s * play >= 0.5 * h * (1.0 - 1e-12)) {
                X[0] = X[2] / k + (double)s * 0.5 * h; /* on the edge, the given output kept */
                return static_engage(L, s, X, 0, key, departing, err);
            }
        *key = DFWB_LOOP_FREE;
        return DFWB_OK;
    }
}

static int loop_fire(dfwb_hy *hy, double t, int kind, double *X, int *key, int *departing, dfwb_err *err)
{
    dfwb_loop *L = (dfwb_loop *)(void *)hy;
    (void)t;
    *departing = -1;
    if (L->plant == DFWB_PLANT_FRICTION) {
        if (kind == DFWB_EVENT_BAND) {
            X[1] = 0.0;
            return friction_rest(L, X, key, departing, err);
        }
        *key = kind == DFWB_EVENT_BREAK_UP ? DFWB_LOOP_SLIDE_UP : DFWB_LOOP_SLIDE_DOWN;
        *departing = 0;
        return DFWB_OK;
    }
    if (L->plant == DFWB_PLANT_BACKLASH) {
        int sigma;
        double w;
        if (kind == DFWB_EVENT_RELEASE) {
            X[3] = 0.0;
            *departing = key_sign(L, hy->key) < 0 ? 0 : 1;
            *key = DFWB_LOOP_FREE;
            return DFWB_OK;
        }
        sigma = kind == DFWB_EVENT_WALL_LOWER ? -1 : 1;
        w = X[3];
        if ((double)sigma * w > 0.0) { /* closing: Newton's impact law, momentum kept */
            const double eps = L->par[3], r2 = L->par[4], next = -eps * w;
            X[1] += r2 * (w - next);
            X[3] = next;
            L->count += 1;
        }
        return backlash_at_wall(L, sigma, X, key, departing, err);
    }
    if (kind == DFWB_EVENT_REVERSE) {
        const int s = key_sign(L, hy->key);
        X[1] = 0.0;
        *key = DFWB_LOOP_FREE;
        *departing = s > 0 ? 0 : 1;
        return DFWB_OK;
    }
    return static_engage(L, kind == DFWB_EVENT_ENGAGE_UP ? 1 : -1, X, 1, key, departing, err);
}

/* -- construction --------------------------------------------------------------------------------- */
static const char *const COORDINATES[4][4] = {
    {NULL}, {"x", "v", NULL, NULL}, {"x1", "v1", "gap", "w"}, {"x", "v", "y", NULL}};
static const char *const COORDINATES_TEXT[4] = {"", "('x', 'v')", "('x1', 'v1', 'gap', 'w')", "('x', 'v', 'y')"};
static const int PLANT_SIZE[4] = {0, 2, 4, 3};
static const int PLANT_PARAMS[4] = {0, DFWB_LOOP_FRICTION_PARAMS, DFWB_LOOP_BACKLASH_PARAMS,
                                    DFWB_LOOP_STATIC_BACKLASH_PARAMS};

/* check() of an integer (a length): "<name> = <n> is out of range: <allowed>" */
static int check_count(dfwb_err *err, const char *name, size_t value, int ok, const char *allowed)
{
    if (ok)
        return DFWB_OK;
    return dfwb_fail(err, DFWB_E_VALUE, "%s = %lu is out of range: %s", name, (unsigned long)value, allowed);
}

/* The plant's checks (the subclass's __init__, the plant's own dfwb_*_check); its parameters; q0. */
static int check_plant(dfwb_loop *L, const double *v, double *q0, dfwb_err *err)
{
    int rc;
    if (L->plant == DFWB_PLANT_FRICTION) {
        const double M = v[DFWB_FRICTION_LOOP_M], B = v[DFWB_FRICTION_LOOP_B], Fc = v[DFWB_FRICTION_LOOP_Fc];
        const double Fs = v[DFWB_FRICTION_LOOP_Fs], x0 = v[DFWB_FRICTION_LOOP_x0], v0 = v[DFWB_FRICTION_LOOP_v0];
        if ((rc = dfwb_friction_check(err, M, B, Fc, Fs, v[DFWB_FRICTION_LOOP_Dv], x0, v0, 1)) != DFWB_OK)
            return rc;
        L->par[0] = M;
        L->par[1] = B;
        L->par[2] = Fc;
        L->par[3] = Fs;
        q0[0] = x0;
        q0[1] = v0;
        return DFWB_OK;
    }
    if (L->plant == DFWB_PLANT_BACKLASH) {
        const double M1 = v[DFWB_BACKLASH_LOOP_M1], M2 = v[DFWB_BACKLASH_LOOP_M2], h = v[DFWB_BACKLASH_LOOP_h];
        const double eps = v[DFWB_BACKLASH_LOOP_eps], gap0 = v[DFWB_BACKLASH_LOOP_gap0];
        const double x1_0 = v[DFWB_BACKLASH_LOOP_x1_0], v1_0 = v[DFWB_BACKLASH_LOOP_v1_0];
        const double v2_0 = v[DFWB_BACKLASH_LOOP_v2_0];
        if ((rc = dfwb_backlash_check(err, M1, M2, h, eps, x1_0, v1_0, v2_0, gap0)) != DFWB_OK)
            return rc;
        L->par[0] = M1;
        L->par[1] = M2;
        L->par[2] = h;
        L->par[3] = eps;
        L->par[4] = M2 / (M1 + M2);
        L->par[5] = 1e-12 * h;
        q0[0] = x1_0;
        q0[1] = v1_0;
        q0[2] = gap0;
        q0[3] = v2_0 - v1_0;
        return DFWB_OK;
    }
    {
        const double M = v[DFWB_STATIC_BACKLASH_LOOP_M], k = v[DFWB_STATIC_BACKLASH_LOOP_k];
        const double h = v[DFWB_STATIC_BACKLASH_LOOP_h], x0 = v[DFWB_STATIC_BACKLASH_LOOP_x0];
        const double v0 = v[DFWB_STATIC_BACKLASH_LOOP_v0];
        if ((rc = dfwb_static_backlash_check(err, M, k, h, x0, v0)) != DFWB_OK)
            return rc;
        L->par[0] = M;
        L->par[1] = k;
        L->par[2] = h;
        q0[0] = x0;
        q0[1] = v0;
        q0[2] = k * x0;
        return DFWB_OK;
    }
}

/* LinearSystem(b, a)'s checks and matrices, then _controller's negation of C and D. */
static int controller(dfwb_loop *L, const double *b, size_t nb, const double *a, size_t na, dfwb_err *err)
{
    char name[32], allowed[96];
    size_t i, j, n = na;
    int rc;
    if ((rc = check_count(err, "order", n, 1 <= n && n <= MAX_ORDER,
                          "the order (the number of denominator coefficients a1..an) must be an integer in 1..8"))
        != DFWB_OK)
        return rc;
    snprintf(allowed, sizeof allowed, "an order-%lu G(s) needs %lu numerator coefficients b0..b%lu",
             (unsigned long)n, (unsigned long)(n + 1), (unsigned long)n);
    if ((rc = check_count(err, "number of numerator coefficients", nb, nb == n + 1, allowed)) != DFWB_OK)
        return rc;
    for (i = 1; i <= n; i++) {
        snprintf(name, sizeof name, "a%d", (int)i);
        snprintf(allowed, sizeof allowed, "a%d must be a finite number", (int)i);
        if ((rc = dfwb_check(err, name, a[i - 1], 1, allowed)) != DFWB_OK)
            return rc;
    }
    for (i = 0; i <= n; i++) {
        snprintf(name, sizeof name, "b%d", (int)i);
        snprintf(allowed, sizeof allowed, "b%d must be a finite number", (int)i);
        if ((rc = dfwb_check(err, name, b[i], 1, allowed)) != DFWB_OK)
            return rc;
    }
    L->order = (int)n;
    for (i = 0; i <= n; i++)
        L->bc[i] = b[i];
    for (i = 0; i < n; i++)
        L->ac[i] = a[i];
    for (i = 0; i < n; i++) { /* A: ones above the diagonal, the last row -a[n - 1 - j]; B = e_n */
        for (j = 0; j < n; j++)
            L->Ac[i][j] = i + 1 < n ? (j == i + 1 ? 1.0 : 0.0) : -a[n - 1 - j];
        L->Bc[i] = i + 1 < n ? 0.0 : 1.0;
    }
    for (i = 1; i <= n; i++) /* C_i = b_(n+1-i) - b0 a_(n+1-i), negated */
        L->C[i - 1] = -(b[n + 1 - i] - b[0] * a[n - i]);
    L->D = -b[0];
    return DFWB_OK;
}

/* The row of f over the state, the section's function, the solver at t = 0 (after the controller is set). */
static void setup(dfwb_loop *L, const double *section)
{
    double section_L[DFWB_HY_DIM];
    int i;
    for (i = 0; i < DFWB_HY_DIM; i++) {
        L->f_row[i] = 0.0;
        section_L[i] = 0.0;
    }
    L->f_row[L->out] += L->D; /* f_row[out] += D, then f_row[m:] = C */
    for (i = 0; i < L->order; i++)
        L->f_row[L->m + i] = L->C[i];
    section_L[L->out] = 1.0;
    L->section = section != NULL ? *section : 0.0;
    dfwb_hy_init(&L->hy, L->m + L->order, loop_system, loop_fire, section != NULL ? section_L : NULL,
                 section != NULL ? -*section : 0.0);
}

int dfwb_loop_new(int plant, const double *params, size_t nparams, const double *b, size_t nb, const double *a,
                  size_t na, const double *z0, size_t nz0, const double *state, size_t nstate, const double *section,
                  dfwb_loop **out, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_loop *L;
    double q0[MAX_PLANT], X[DFWB_HY_DIM];
    char name[16], allowed[160];
    int rc, m, n, i, key, departing;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_new: NULL out");
    *out = NULL;
    if (plant < DFWB_PLANT_FRICTION || plant > DFWB_PLANT_STATIC_BACKLASH)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_new: no plant kind %d", plant);
    if (params == NULL || nparams != (size_t)PLANT_PARAMS[plant] || (b == NULL && nb > 0) || (a == NULL && na > 0)
        || (z0 == NULL && nz0 > 0) || (state == NULL && nstate > 0))
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_new: %s needs %d parameters and arrays for its lengths",
                         dfwb_plant_name(plant), PLANT_PARAMS[plant]);
    L = (dfwb_loop *)calloc(1, sizeof *L);
    if (L == NULL)
        return dfwb_fail(&err, DFWB_E_MEMORY, "out of memory (a loop)");
    L->plant = plant;
    L->m = m = PLANT_SIZE[plant];
    L->out = plant == DFWB_PLANT_STATIC_BACKLASH ? 2 : 0;
    rc = check_plant(L, params, q0, &err);
    if (rc == DFWB_OK)
        rc = controller(L, b, nb, a, na, &err);
    if (rc != DFWB_OK) {
        free(L);
        return rc;
    }
    n = L->order;
    for (i = 0; i < m; i++)
        X[i] = q0[i];
    for (i = 0; i < n; i++)
        X[m + i] = 0.0;
    if (state != NULL) { /* the whole loop state: the plant's coordinates, then z */
        snprintf(allowed, sizeof allowed, "the loop's state has %d plant coordinates %s and %d controller states", m,
                 COORDINATES_TEXT[plant], n);
        rc = check_count(&err, "length of state", nstate, nstate == (size_t)(m + n), allowed);
        for (i = 0; rc == DFWB_OK && i < m; i++) {
            snprintf(allowed, sizeof allowed, "%s must be a finite number", COORDINATES[plant][i]);
            rc = dfwb_check(&err, COORDINATES[plant][i], state[i], 1, allowed);
        }
        if (rc == DFWB_OK && plant == DFWB_PLANT_BACKLASH) {
            const double h = L->par[2];
            char rh[DFWB_REPR_SIZE];
            dfwb_repr(h, rh);
            snprintf(allowed, sizeof allowed, "the gap must be in [0, h] = [0, %s] (m)", rh);
            rc = dfwb_check(&err, "gap", state[2], 0.0 <= state[2] && state[2] <= h, allowed);
        } else if (rc == DFWB_OK && plant == DFWB_PLANT_STATIC_BACKLASH) {
            const double play = state[0] - state[2] / L->par[1];
            char rh[DFWB_REPR_SIZE];
            dfwb_repr(0.5 * L->par[2], rh);
            snprintf(allowed, sizeof allowed, "the play x - y/k must be within +-h/2 = %s (m)", rh);
            rc = dfwb_check(&err, "x - y/k", play, fabs(play) <= 0.5 * L->par[2] * (1.0 + 1e-9), allowed);
        }
        if (rc == DFWB_OK) {
            for (i = 0; i < m + n; i++)
                X[i] = state[i];
            z0 = state + m;
            nz0 = (size_t)n;
        }
    } else if (z0 != NULL) {
        for (i = 0; i < n && (size_t)i < nz0; i++)
            X[m + i] = z0[i];
    } else {
        nz0 = (size_t)n;
    }
    if (rc == DFWB_OK) {
        snprintf(allowed, sizeof allowed, "z0 needs %d components (the controller's order)", n);
        rc = check_count(&err, "length of z0", nz0, nz0 == (size_t)n, allowed);
    }
    for (i = 0; rc == DFWB_OK && z0 != NULL && i < n; i++) {
        snprintf(name, sizeof name, "z%d_0", i + 1);
        snprintf(allowed, sizeof allowed, "the controller state z%d_0 must be a finite number", i + 1);
        rc = dfwb_check(&err, name, z0[i], 1, allowed);
    }
    if (rc == DFWB_OK && section != NULL)
        rc = dfwb_check(&err, "section", *section, 1, "the section level must be a finite number");
    if (rc != DFWB_OK) {
        free(L);
        return rc;
    }
    setup(L, section);
    rc = loop_initial(L, X, &key, &departing, &err);
    if (rc == DFWB_OK)
        rc = dfwb_hy_start(&L->hy, 0.0, X, key, departing, &err);
    rc = dfwb_err_finish(&err, rc);
    if (rc != DFWB_OK) {
        dfwb_loop_free(L);
        return rc;
    }
    *out = L;
    return DFWB_OK;
}

/* -- the API ------------------------------------------------------------------------------------ */
int dfwb_loop_advance(dfwb_loop *p, double t_end, unsigned long long stop, long long *budget_left,
                      long long budget_total, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_advance: NULL instance");
    return dfwb_err_finish(&err, dfwb_hy_advance(&p->hy, t_end, stop, budget_left, budget_total, &err));
}

int dfwb_loop_stopped(const dfwb_loop *p) { return p == NULL ? 0 : p->hy.stopped; }

int dfwb_loop_sample(dfwb_loop *p, const double *times, size_t n, double *states, long long *budget_left,
                     long long budget_total, char *errbuf, size_t errlen)
{
    dfwb_err err;
    size_t i;
    int rc = DFWB_OK;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL || (n > 0 && (times == NULL || states == NULL)))
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_sample: NULL argument");
    for (i = 0; i < n && rc == DFWB_OK; i++) {
        rc = dfwb_hy_advance(&p->hy, times[i], 0, budget_left, budget_total, &err);
        if (rc == DFWB_OK)
            dfwb_hy_state(&p->hy, states + i * (size_t)p->hy.n);
    }
    return dfwb_err_finish(&err, rc);
}

double dfwb_loop_time(const dfwb_loop *p) { return p == NULL ? NAN : p->hy.t; }
long long dfwb_loop_events(const dfwb_loop *p) { return p == NULL ? 0 : p->hy.events; }
int dfwb_loop_plant(const dfwb_loop *p) { return p == NULL ? 0 : p->plant; }
int dfwb_loop_order(const dfwb_loop *p) { return p == NULL ? 0 : p->order; }
int dfwb_loop_size(const dfwb_loop *p) { return p == NULL ? 0 : p->m + p->order; }
int dfwb_loop_mode(const dfwb_loop *p) { return p == NULL ? -1 : p->hy.key; }
long long dfwb_loop_counter(const dfwb_loop *p) { return p == NULL ? 0 : p->count; }

void dfwb_loop_state(const dfwb_loop *p, double *X)
{
    if (p != NULL && X != NULL)
        dfwb_hy_state(&p->hy, X);
}

double dfwb_loop_output(const dfwb_loop *p)
{
    double X[DFWB_HY_DIM];
    if (p == NULL)
        return NAN;
    dfwb_hy_state(&p->hy, X);
    return X[p->out];
}

double dfwb_loop_force(const dfwb_loop *p, const double *X)
{
    return p == NULL || X == NULL ? NAN : loop_force(p, X);
}

void dfwb_loop_parameters(const dfwb_loop *p, double out[6])
{
    int i;
    for (i = 0; i < 6; i++)
        out[i] = p == NULL ? NAN : p->par[i];
}

void dfwb_loop_controller(const dfwb_loop *p, double *Ac, double *Bc, double *C, double *D)
{
    int i, j, n;
    if (p == NULL)
        return;
    n = p->order;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++)
            if (Ac != NULL)
                Ac[i * n + j] = p->Ac[i][j];
        if (Bc != NULL)
            Bc[i] = p->Bc[i];
        if (C != NULL)
            C[i] = p->C[i];
    }
    if (D != NULL)
        *D = p->D;
}

size_t dfwb_loop_crossings_read(dfwb_loop *p, double *t, double *X, size_t max)
{
    size_t i, k, width;
    if (p == NULL)
        return 0;
    if (t == NULL || X == NULL || max == 0)
        return p->hy.ncrossings;
    k = max < p->hy.ncrossings ? max : p->hy.ncrossings;
    width = (size_t)p->hy.n + 1;
    for (i = 0; i < k; i++) {
        t[i] = p->hy.crossings[i * width];
        memcpy(X + i * (width - 1), p->hy.crossings + i * width + 1, (width - 1) * sizeof *X);
    }
    if (k < p->hy.ncrossings)
        memmove(p->hy.crossings, p->hy.crossings + k * width, (p->hy.ncrossings - k) * width * sizeof(double));
    p->hy.ncrossings -= k;
    return k;
}

unsigned long long dfwb_loop_crossings_dropped(const dfwb_loop *p) { return p == NULL ? 0 : p->hy.crossings_dropped; }

int dfwb_loop_modes_built(const dfwb_loop *p)
{
    int mask = 0, i;
    if (p == NULL)
        return 0;
    for (i = 0; i < DFWB_HY_MODES; i++)
        if (p->hy.modes[i] != NULL)
            mask |= 1 << i;
    return mask;
}

int dfwb_loop_build_modes(dfwb_loop *p, int mask, char *errbuf, size_t errlen)
{
    dfwb_err err;
    int i, rc = DFWB_OK;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_build_modes: NULL instance");
    for (i = 0; i < DFWB_HY_MODES && rc == DFWB_OK; i++)
        if ((mask >> i) & 1)
            if (dfwb_hy_mode_of(&p->hy, i, &err) == NULL)
                rc = err.code != DFWB_OK ? err.code : DFWB_E_MATH;
    return dfwb_err_finish(&err, rc);
}

int dfwb_loop_mode_info(const dfwb_loop *p, int key, double *h, int *terms)
{
    const dfwb_hy_mode *m;
    if (p == NULL || key < 0 || key >= DFWB_HY_MODES || p->hy.modes[key] == NULL)
        return 0;
    m = p->hy.modes[key];
    if (h != NULL)
        *h = m->h;
    if (terms != NULL)
        *terms = m->terms;
    return 1;
}

dfwb_loop *dfwb_loop_copy(const dfwb_loop *p)
{
    dfwb_loop *copy;
    if (p == NULL)
        return NULL;
    copy = (dfwb_loop *)malloc(sizeof *copy);
    if (copy == NULL)
        return NULL;
    memcpy(copy, p, sizeof *copy);
    if (!dfwb_hy_copy(&copy->hy, &p->hy)) {
        free(copy);
        return NULL;
    }
    return copy;
}

void dfwb_loop_free(dfwb_loop *p)
{
    if (p == NULL)
        return;
    dfwb_hy_free(&p->hy);
    free(p);
}

void dfwb_loop_log(dfwb_loop *p, size_t capacity)
{
    if (p != NULL)
        dfwb_log_enable(&p->hy.log, capacity);
}

size_t dfwb_loop_log_read(dfwb_loop *p, double *t, int *kind, size_t max)
{
    return p == NULL ? 0 : dfwb_log_read(&p->hy.log, t, kind, max);
}

unsigned long long dfwb_loop_log_dropped(const dfwb_loop *p) { return p == NULL ? 0 : p->hy.log.dropped; }

int dfwb_loop_section(const dfwb_loop *p, double *level)
{
    if (p == NULL || !p->hy.has_section)
        return 0;
    if (level != NULL)
        *level = p->section;
    return 1;
}

int dfwb_loop_same_parameters(const dfwb_loop *a, const dfwb_loop *b)
{
    int i;
    if (a == NULL || b == NULL || a->plant != b->plant || a->order != b->order
        || a->hy.has_section != b->hy.has_section || !dfwb_same_double(a->section, b->section))
        return 0;
    for (i = 0; i < 6; i++)
        if (!dfwb_same_double(a->par[i], b->par[i]))
            return 0;
    for (i = 0; i <= MAX_ORDER; i++)
        if (!dfwb_same_double(a->bc[i], b->bc[i]) || (i < MAX_ORDER && !dfwb_same_double(a->ac[i], b->ac[i])))
            return 0;
    return 1;
}

/* -- states as bytes ---------------------------------------------------------------------------- */
/* The state's fields, in order (writing leaves the loop as it is; *mask: the modes built). */
static void loop_io(dfwb_io *io, dfwb_loop *L, int *mask)
{
    dfwb_hy *hy = &L->hy;
    int i;
    for (i = 0; i < 4; i++)
        dfwb_io_f64(io, &L->par[i]);
    dfwb_io_int(io, &L->order);
    for (i = 0; i <= MAX_ORDER; i++)
        dfwb_io_f64(io, &L->bc[i]);
    for (i = 0; i < MAX_ORDER; i++)
        dfwb_io_f64(io, &L->ac[i]);
    dfwb_io_int(io, &hy->has_section);
    dfwb_io_f64(io, &L->section);
    dfwb_io_f64(io, &hy->t);
    dfwb_io_i64(io, &hy->events);
    dfwb_io_i64(io, &L->count);
    dfwb_io_int(io, &hy->key);
    dfwb_io_int(io, mask);
    dfwb_io_int(io, &hy->watching);
    dfwb_io_f64(io, &hy->time_rounding);
    dfwb_io_int(io, &hy->ndeparting);
    dfwb_io_int(io, &hy->departing[0]);
    dfwb_io_int(io, &hy->departing[1]);
    dfwb_io_f64(io, &hy->a);
    for (i = 0; i < DFWB_HY_DIM; i++)
        dfwb_io_f64(io, &hy->X[i]);
    dfwb_io_int(io, &hy->first);
    dfwb_io_int(io, &hy->searched);
    dfwb_io_int(io, &hy->has_event);
    dfwb_io_f64(io, &hy->event_tau);
    dfwb_io_int(io, &hy->event_kind);
}

static size_t loop_payload(void)
{
    static const dfwb_loop zero;
    dfwb_loop tmp = zero;
    dfwb_io io;
    int mask = 0;
    dfwb_io_writer(&io, NULL);
    loop_io(&io, &tmp, &mask);
    return io.pos;
}

int dfwb_loop_to_bytes(const dfwb_loop *p, unsigned char *buf, size_t buflen, size_t *size, char *errbuf,
                       size_t errlen)
{
    dfwb_err err;
    const size_t payload = loop_payload(), needed = DFWB_STATE_HEADER + payload;
    dfwb_loop tmp;
    dfwb_io io;
    int rc, mask, i;
    dfwb_err_init(&err, errbuf, errlen);
    if (size != NULL)
        *size = needed;
    if (buf == NULL)
        return DFWB_OK;
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_to_bytes: NULL instance");
    rc = dfwb_state_buffer(needed, buflen, &err);
    if (rc != DFWB_OK)
        return rc;
    memcpy(&tmp, p, sizeof tmp); /* canonical: what is unused written as zeros */
    for (i = tmp.hy.ndeparting; i < 2; i++)
        tmp.hy.departing[i] = 0;
    if (!tmp.hy.has_event) {
        tmp.hy.event_tau = 0.0;
        tmp.hy.event_kind = 0;
    }
    for (i = tmp.hy.n; i < DFWB_HY_DIM; i++)
        tmp.hy.X[i] = 0.0;
    mask = dfwb_loop_modes_built(p);
    dfwb_io_writer(&io, buf + DFWB_STATE_HEADER);
    loop_io(&io, &tmp, &mask);
    dfwb_state_header(buf, DFWB_STATE_FRICTION_LOOP - DFWB_PLANT_FRICTION + p->plant, payload);
    return DFWB_OK;
}

/* A refusal of dfwb_loop_new's checks, as a state's: DFWB_E_STATE naming the state. */
static int state_refused(dfwb_err *err, const char *what, const char *message)
{
    return dfwb_fail(err, DFWB_E_STATE, "the state's %s are refused: %s", what, message);
}

int dfwb_loop_from_bytes(int plant, const unsigned char *buf, size_t len, dfwb_loop **out, char *errbuf,
                         size_t errlen)
{
    dfwb_err err, local;
    dfwb_loop *L, s;
    char message[512];
    double values[8] = {0.0}, q0[MAX_PLANT];
    int rc, mask = 0, i, n;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_from_bytes: NULL out");
    *out = NULL;
    if (plant < DFWB_PLANT_FRICTION || plant > DFWB_PLANT_STATIC_BACKLASH)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_from_bytes: no plant kind %d", plant);
    rc = dfwb_state_open(buf, len, DFWB_STATE_FRICTION_LOOP - DFWB_PLANT_FRICTION + plant, loop_payload(), &err);
    if (rc != DFWB_OK)
        return rc;
    {
        static const dfwb_loop zero;
        dfwb_io io;
        s = zero;
        dfwb_io_reader(&io, buf + DFWB_STATE_HEADER, len - DFWB_STATE_HEADER);
        loop_io(&io, &s, &mask);
        if (io.bad_int)
            return dfwb_fail(&err, DFWB_E_STATE, "the state has an integer field out of range");
    }
    L = (dfwb_loop *)calloc(1, sizeof *L);
    if (L == NULL)
        return dfwb_fail(&err, DFWB_E_MEMORY, "out of memory (a loop)");
    L->plant = plant;
    L->m = PLANT_SIZE[plant];
    L->out = plant == DFWB_PLANT_STATIC_BACKLASH ? 2 : 0;
    /* the parameters and the controller, checked as dfwb_loop_new checks them */
    for (i = 0; i < 4; i++)
        values[i] = s.par[i];
    if (plant == DFWB_PLANT_BACKLASH)
        values[7] = 0.0; /* gap0: not state */
    dfwb_err_init(&local, message, sizeof message);
    rc = plant == DFWB_PLANT_STATIC_BACKLASH && s.par[3] != 0.0
             ? dfwb_state_check(&err, "parameter 4", s.par[3], 0, "must be 0 (a static backlash has 3)")
             : (check_plant(L, values, q0, &local) != DFWB_OK ? state_refused(&err, "parameters", message) : DFWB_OK);
    if (rc == DFWB_OK)
        rc = dfwb_state_check_int(&err, "order", s.order, 1 <= s.order && s.order <= MAX_ORDER, "must be in 1..8");
    n = rc == DFWB_OK ? s.order : 0;
    for (i = n; rc == DFWB_OK && i < MAX_ORDER; i++)
        if (s.bc[i + 1] != 0.0 || s.ac[i] != 0.0 || signbit(s.bc[i + 1]) || signbit(s.ac[i]))
            rc = dfwb_state_check_int(&err, "controller coefficients above the order", i + 1, 0, "must be 0");
    if (rc == DFWB_OK && controller(L, s.bc, (size_t)n + 1, s.ac, (size_t)n, &local) != DFWB_OK)
        rc = state_refused(&err, "controller coefficients", message);
    if (rc == DFWB_OK)
        rc = dfwb_state_check_int(&err, "section flag", s.hy.has_section, s.hy.has_section == 0
                                  || s.hy.has_section == 1, "must be 0 or 1");
    if (rc == DFWB_OK)
        rc = dfwb_state_check(&err, "section", s.section, s.hy.has_section ? isfinite(s.section)
                              : s.section == 0.0 && !signbit(s.section), "must be finite (0 without a section)");
    if (rc != DFWB_OK) {
        free(L);
        return rc;
    }
    setup(L, s.hy.has_section ? &s.section : NULL);
    if ((rc = dfwb_state_check(&err, "t", s.hy.t, isfinite(s.hy.t) && s.hy.t >= 0.0, "must be finite and >= 0"))
            != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "events", s.hy.events, s.hy.events >= 0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "count", s.count, s.count >= 0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "mode", s.hy.key, 0 <= s.hy.key && s.hy.key < DFWB_HY_MODES,
                                      "must be a mode key 0..2")) != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "modes built", mask, 0 <= mask && mask < (1 << DFWB_HY_MODES)
                                      && ((mask >> s.hy.key) & 1), "must be a set of modes with the current one"))
               != DFWB_OK) {
        dfwb_loop_free(L);
        return rc;
    }
    for (i = 0; i < DFWB_HY_MODES; i++)
        if (((mask >> i) & 1) && dfwb_hy_mode_of(&L->hy, i, &local) == NULL) {
            dfwb_loop_free(L);
            return state_refused(&err, "modes (built from its parameters)",
                                 local.code != DFWB_OK ? message : "(34, 'Numerical result out of range')");
        }
    L->count = s.count;
    L->hy.t = s.hy.t;
    L->hy.events = s.hy.events;
    L->hy.key = s.hy.key;
    L->hy.watching = s.hy.watching;
    L->hy.time_rounding = s.hy.time_rounding;
    L->hy.ndeparting = s.hy.ndeparting;
    L->hy.departing[0] = s.hy.departing[0];
    L->hy.departing[1] = s.hy.departing[1];
    L->hy.a = s.hy.a;
    memcpy(L->hy.X, s.hy.X, sizeof L->hy.X);
    L->hy.first = s.hy.first;
    L->hy.searched = s.hy.searched;
    L->hy.has_event = s.hy.has_event;
    L->hy.event_tau = s.hy.event_tau;
    L->hy.event_kind = s.hy.event_kind;
    rc = dfwb_hy_resume(&L->hy, &err);
    if (rc != DFWB_OK) {
        dfwb_loop_free(L);
        return rc;
    }
    *out = L;
    return DFWB_OK;
}
