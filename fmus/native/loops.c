/* loops.c - a plant in feedback with a linear controller, as an exact hybrid system: a port of fmus/loops.py's
 * FeedbackLoop on the solver of hybrid.c. What is the plant's (its modes, checks and switching: FrictionLoop,
 * BacklashLoop, StaticBacklashLoop) is its dfwb_loop_class (loop.h), in the plant's own file, found through its
 * dfwb_plant_class. The API is documented in dfwb_core.h.
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
#include "loop.h"
#include "plant.h"

#define MAX_ORDER DFWB_LOOP_MAX_ORDER
#define MAX_PLANT DFWB_LOOP_PLANT_MAX
#define MAX_PLAY 1e3 /* a backlash inverse's h_hat at most [m] (compensation.MAX_PLAY) */

void dfwb_loop_add_event(dfwb_plant_mode *pm, int kind, double l1, double l2, double l3, double l4, double Lf,
                         double l0)
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


/* The index of a backlash inverse's correction in the solver's state: after z and a dither's oscillator. */
static int inverse_at(const dfwb_loop *L) { return L->m + L->order + (L->has_dither ? 2 : 0); }

/* FeedbackLoop.system: the loop's A, c and event functions of a mode */
static int loop_system(dfwb_hy *hy, int key, dfwb_hy_mode *mode, dfwb_err *err)
{
    const dfwb_loop *L = (const dfwb_loop *)(const void *)hy;
    /* m + n, a dither's oscillator (s, c) and a backlash inverse's correction w (the controller sees y + w) */
    const int m = L->m, n = L->order, size = hy->n, w = inverse_at(L);
    dfwb_plant_mode pm;
    double on_plant[DFWB_HY_DIM]; /* the force on the plant: f = D (y + w) + C z, and the dither's s */
    int i, j, e;
    double k;
    (void)err;
    memset(&pm, 0, sizeof pm);
    L->cls->mode(L, key, &pm);
    k = L->has_coulomb && L->F_hat != 0.0 ? L->F_hat * (double)L->cls->slip(key) : 0.0;
    mode->n = size;
    for (j = 0; j < size; j++)
        on_plant[j] = L->has_dither && j == m + n ? 1.0 : L->f_row[j];
    for (i = 0; i < m; i++) /* row = list(P[i]) + [0.0] * (n + e); [value + phi[i] * fv ...] */
        for (j = 0; j < size; j++)
            mode->A[i][j] = (j < m ? pm.P[i][j] : 0.0) + pm.phi[i] * on_plant[j];
    for (i = 0; i < n; i++) { /* row = [0.0] * m + list(Ac[i]) + [0.0] * e; row[out] += Bc[i] (held: deadband) */
        for (j = 0; j < size; j++)
            mode->A[m + i][j] = j < m || j >= m + n ? 0.0 : L->Ac[i][j - m];
        mode->A[m + i][L->out] += L->band || i > 0 ? L->Bc[i] : L->Bc[0] - 1.0 / L->w[0];
        if (L->has_inverse)
            mode->A[m + i][w] = mode->A[m + i][L->out];
    }
    if (L->has_dither) { /* s' = w_d c, c' = -w_d s */
        for (j = 0; j < size; j++)
            mode->A[m + n][j] = mode->A[m + n + 1][j] = 0.0;
        mode->A[m + n][m + n + 1] = L->w_d;
        mode->A[m + n + 1][m + n] = -L->w_d;
    }
    if (L->has_inverse) /* w' = 0: set where the play makes contact */
        for (j = 0; j < size; j++)
            mode->A[w][j] = 0.0;
    for (i = 0; i < size; i++) /* the compensator's force k, constant in the mode: the plant sees f + s + k */
        mode->c[i] = i < m ? pm.p[i] + pm.phi[i] * k : 0.0;
    mode->nev = pm.nev;
    for (e = 0; e < pm.nev; e++) {
        mode->ev[e].kind = pm.kind[e];
        for (j = 0; j < size; j++)
            mode->ev[e].L[j] = (j < m ? pm.Lq[e][j] : 0.0) + pm.Lf[e] * on_plant[j];
        mode->ev[e].l0 = pm.l0[e] + pm.Lf[e] * k;
    }
    if (L->d > 0.0) { /* outside: band * y - d > 0; within: d - y > 0 and d + y > 0 */
        const int sides = L->band ? 1 : 2;
        for (e = 0; e < sides; e++) {
            dfwb_hy_event *ev = &mode->ev[mode->nev++];
            ev->kind = DFWB_EVENT_DEADBAND;
            for (j = 0; j < size; j++)
                ev->L[j] = 0.0;
            ev->L[L->out] = L->band ? (double)L->band : (e == 0 ? -1.0 : 1.0);
            if (L->has_inverse)
                ev->L[w] = ev->L[L->out];
            ev->l0 = L->band ? -L->d : L->d;
        }
    }
    if (pm.nonlinear) { /* (row, col, law): plant coordinates first, so the same indices in the loop's state */
        mode->integrated = 1;
        mode->row = pm.row;
        mode->col = pm.col;
        mode->sign = pm.sign;
        mode->feature = pm.feature;
    }
    return DFWB_OK;
}

/* The class's law of its integrated modes, seen from the hybrid solver (the loop's first member). */
static double loop_law(const dfwb_hy *hy, int sign, double v)
{
    const dfwb_loop *L = (const dfwb_loop *)(const void *)hy;
    return L->cls->law(L, sign, v);
}

static double loop_law_slope(const dfwb_hy *hy, int sign, double v)
{
    const dfwb_loop *L = (const dfwb_loop *)(const void *)hy;
    return L->cls->law_slope(L, sign, v);
}

double dfwb_loop_feedback(const dfwb_loop *L, const double *X)
{
    double s = 0.0;
    int i;
    for (i = 0; i < L->order; i++)
        s += L->C[i] * X[L->m + i];
    return L->D * (X[L->out] + (L->has_inverse ? X[inverse_at(L)] : 0.0)) + s;
}

/* FeedbackLoop._contact: a backlash inverse's correction in X where the play touched its side (0: none). */
static void contact(const dfwb_loop *L, int side, double *X)
{
    if (L->has_inverse && side)
        X[inverse_at(L)] = L->cls->half_play(L) * L->h_hat * (double)side;
}

/* -- the switching logic: the plant's (initial at t = 0, _fire) ------------------------------------------- */
static int loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    *departing = -1;
    return L->cls->initial(L, X, key, departing, err);
}

/* The deadband's side, and the hybrid's variant that keys its modes: band 1 (or none) 0, band 0 1, band -1 2. */
static void set_band(dfwb_loop *L, int band)
{
    L->band = band;
    L->hy.variant = band == 1 ? 0 : band == 0 ? 1 : 2;
}

/* FeedbackLoop._reset: clear the controller's integrator in X, its other modes kept: z -= (w . z / w_1) e_1. */
static void reset_integrator(const dfwb_loop *L, double *X)
{
    double s = 0.0;
    int i;
    for (i = 0; i < L->order; i++)
        s += L->w[i] * X[L->m + i];
    X[L->m] -= s / L->w[0];
}

/* The index of the first deadband edge in the mode of key at the current side (0 when the mode is refused). */
static int first_edge(dfwb_loop *L, int key, dfwb_err *err)
{
    const dfwb_hy_mode *m = dfwb_hy_mode_of(&L->hy, key, err);
    int first = 0;
    while (m != NULL && first < m->nev && m->ev[first].kind != DFWB_EVENT_DEADBAND)
        first++;
    return m == NULL ? -1 : first;
}

/* FeedbackLoop._cross_edge: from outside, in through the edge of its side; from within, out where the edge
 * function falls through zero (its trend); the edge crossed departs in the new mode. */
static int cross_edge(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    const int key0 = L->hy.key;
    int first = first_edge(L, key0, err), sign, rc;
    *key = key0;
    if (first < 0)
        return err->code != DFWB_OK ? err->code : DFWB_E_MATH;
    if (L->band) {
        *departing = first + (L->band > 0 ? 0 : 1);
        set_band(L, 0);
        return DFWB_OK;
    }
    rc = dfwb_hy_after(&L->hy, key0, first, X, &sign, err);
    if (rc != DFWB_OK)
        return rc;
    set_band(L, sign < 0 ? 1 : -1);
    *departing = first_edge(L, key0, err);
    return *departing < 0 ? (err->code != DFWB_OK ? err->code : DFWB_E_MATH) : DFWB_OK;
}

/* FeedbackLoop._switch: a deadband edge switches its side (the mode goes on); the reset acts where the plant
 * comes to rest, before the plant's own switching. */
static int loop_fire(dfwb_hy *hy, double t, int kind, double *X, int *key, int *departing, dfwb_err *err)
{
    dfwb_loop *L = (dfwb_loop *)(void *)hy;
    (void)t;
    *departing = -1;
    if (kind == DFWB_EVENT_DEADBAND)
        return cross_edge(L, X, key, departing, err);
    if (L->reset && kind == L->cls->rest_kind)
        reset_integrator(L, X);
    if (L->has_inverse) /* the play's touch: the correction jumps before the plant's logic, which sees its force */
        contact(L, L->cls->contact(kind), X);
    return L->cls->fire(L, kind, X, key, departing, err);
}

/* The loop class of a plant kind (NULL: none). */
static const dfwb_loop_class *loop_plant_of(int kind)
{
    const dfwb_plant_class *cls = dfwb_plant_class_of(kind);
    return cls == NULL ? NULL : cls->loop;
}

/* -- construction --------------------------------------------------------------------------------- */
/* check() of an integer (a length): "<name> = <n> is out of range: <allowed>" */
static int check_count(dfwb_err *err, const char *name, size_t value, int ok, const char *allowed)
{
    if (ok)
        return DFWB_OK;
    return dfwb_fail(err, DFWB_E_VALUE, "%s = %lu is out of range: %s", name, (unsigned long)value, allowed);
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

/* The compensators of compensation[7] = {coulomb 0/1, F_hat, reset 0/1, d, a, w_d, h_hat} (NULL: none), checked
 * in the order and with the texts of Coulomb, Deadband, Dither, BacklashInverse and FeedbackLoop.__init__ (after
 * the controller's own checks): F_hat, d, a, w_d, h_hat, the one integrator the reset and the deadband need (a:
 * G's a1..an, checked), a plant where the reset acts, a plant with a play for the backlash inverse. */
static int compensators(dfwb_loop *L, const double *compensation, const double *a, size_t na, dfwb_err *err)
{
    char text[8 + (DFWB_REPR_SIZE + 2) * MAX_ORDER];
    size_t i, used;
    int rc;
    L->band = 1;
    if (compensation == NULL)
        return DFWB_OK;
    if (!(compensation[0] == 0.0 || compensation[0] == 1.0) || !(compensation[2] == 0.0 || compensation[2] == 1.0))
        return dfwb_fail(err, DFWB_E_ARGUMENT, "dfwb_loop_new: the compensation's flags must be 0 or 1");
    L->has_coulomb = compensation[0] == 1.0;
    L->F_hat = L->has_coulomb ? compensation[1] : 0.0;
    L->reset = compensation[2] == 1.0;
    L->d = compensation[3];
    L->a_d = compensation[4];
    L->w_d = compensation[5];
    L->h_hat = compensation[6];
    if ((L->has_coulomb && (rc = dfwb_check(err, "F_hat", L->F_hat, L->F_hat >= 0.0,
                                            "a finite number of newtons, at least 0")) != DFWB_OK)
        || (rc = dfwb_check(err, "d", L->d, L->d >= 0.0,
                            "the error band of the integrator deadband, a finite number at least 0")) != DFWB_OK
        || (rc = dfwb_check(err, "a", L->a_d, L->a_d >= 0.0,
                            "the dither's amplitude, a finite number of newtons, at least 0")) != DFWB_OK)
        return rc;
    if (L->a_d > 0.0 && (rc = dfwb_check(err, "w_d", L->w_d, L->w_d > 0.0,
                                         "the dither's angular frequency, a finite number of rad/s above 0")) != DFWB_OK)
        return rc;
    if ((rc = dfwb_check(err, "h_hat", L->h_hat, L->h_hat >= 0.0 && L->h_hat <= MAX_PLAY,
                         "the backlash inverse's estimated play, a number of metres from 0 to 1000")) != DFWB_OK)
        return rc;
    L->has_dither = L->a_d > 0.0; /* a = 0: no dither (its w_d then 0, as a state holds it) */
    L->has_inverse = L->h_hat > 0.0;
    if (!L->has_dither)
        L->w_d = 0.0;
    if (L->reset || L->d > 0.0) { /* integrator(a): w = (a_(n-1), ..., a_1, 1) */
        if (na == 0 || a[na - 1] != 0.0 || (na > 1 && a[na - 2] == 0.0)) {
            used = (size_t)snprintf(text, sizeof text, "[");
            for (i = 0; i < na; i++) {
                char r[DFWB_REPR_SIZE];
                dfwb_repr(a[i], r);
                used += (size_t)snprintf(text + used, sizeof text - used, "%s%s", i ? ", " : "", r);
            }
            snprintf(text + used, sizeof text - used, "]");
            return dfwb_fail(err, DFWB_E_VALUE, "integrator management (reset, deadband) needs a controller with one "
                             "integrator, a simple pole at s = 0: this G(s) has %s (its denominator's coefficients "
                             "after s^n: %s)", na == 0 || a[na - 1] != 0.0 ? "none" : "a double one", text);
        }
        for (i = 0; i + 1 < na; i++)
            L->w[i] = a[na - 2 - i];
        L->w[na - 1] = 1.0;
        if (!(fabs(1.0 / L->w[0]) < INFINITY)) { /* the held integrator's column has 1 / w_1 */
            char r[DFWB_REPR_SIZE];
            dfwb_repr(L->w[0], r);
            return dfwb_fail(err, DFWB_E_VALUE, "a%d = %s is out of range: integrator management (reset, deadband) "
                             "needs 1 / a%d finite (the integrator's coordinate is a%d z_1 + ...)", (int)na - 1, r,
                             (int)na - 1, (int)na - 1);
        }
    }
    if (L->reset && L->cls->rest_kind == 0)
        return dfwb_fail(err, DFWB_E_VALUE, "the integrator reset needs a plant that comes to rest; %s has no such "
                         "event", L->cls->python_name);
    if (L->has_inverse && L->cls->contact == NULL)
        return dfwb_fail(err, DFWB_E_VALUE, "the backlash inverse needs a plant with a play between the mass and the "
                         "output; %s has none", L->cls->python_name);
    return DFWB_OK;
}

/* The Coulomb feedforward of the velocity (F_hat > 0) needs the plant's slip (Python refuses it where the loop's
 * first mode is built: after every other check). */
static int coulomb_fits(const dfwb_loop *L, dfwb_err *err)
{
    if (L->has_coulomb && L->F_hat != 0.0 && L->cls->slip == NULL)
        return dfwb_fail(err, DFWB_E_VALUE, "the Coulomb feedforward of the velocity needs a plant with friction; %s "
                         "has none (use the controller's signal)", L->cls->python_name);
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
    if (L->has_inverse) /* f = D (y + w) + C z */
        L->f_row[inverse_at(L)] = L->D;
    section_L[L->out] = 1.0;
    L->section = section != NULL ? *section : 0.0;
    dfwb_hy_init(&L->hy, inverse_at(L) + L->has_inverse, loop_system, loop_fire,
                 section != NULL ? section_L : NULL,
                 section != NULL ? -*section : 0.0);
    if (L->cls->law != NULL) {
        L->hy.law = loop_law;
        L->hy.law_slope = loop_law_slope;
    }
    L->hy.rtol = L->cls->rtol >= 0 ? L->par[L->cls->rtol] : 0.0;
}

int dfwb_loop_new(int plant, const double *params, size_t nparams, const double *b, size_t nb, const double *a,
                  size_t na, const double *z0, size_t nz0, const double *state, size_t nstate, const double *section,
                  const double *compensation, dfwb_loop **out, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_loop *L;
    const dfwb_loop_class *cls;
    double q0[MAX_PLANT], X[DFWB_HY_DIM];
    char name[16], allowed[160];
    int rc, m, n, i, key, departing;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_new: NULL out");
    *out = NULL;
    cls = loop_plant_of(plant);
    if (cls == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_new: no plant kind %d", plant);
    if (params == NULL || nparams != cls->nparams || (b == NULL && nb > 0) || (a == NULL && na > 0)
        || (z0 == NULL && nz0 > 0) || (state == NULL && nstate > 0))
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_new: %s needs %d parameters and arrays for its lengths",
                         dfwb_plant_name(plant), (int)cls->nparams);
    L = (dfwb_loop *)calloc(1, sizeof *L);
    if (L == NULL)
        return dfwb_fail(&err, DFWB_E_MEMORY, "out of memory (a loop)");
    L->cls = cls;
    L->plant = plant;
    L->m = m = cls->size;
    L->out = cls->out;
    rc = cls->check(L, params, q0, &err);
    if (rc == DFWB_OK)
        rc = controller(L, b, nb, a, na, &err);
    if (rc == DFWB_OK)
        rc = compensators(L, compensation, a, na, &err);
    if (rc != DFWB_OK) {
        free(L);
        return rc;
    }
    n = L->order;
    for (i = 0; i < m; i++)
        X[i] = q0[i];
    for (i = 0; i < n; i++)
        X[m + i] = 0.0;
    X[m + n] = 0.0; /* a dither's oscillator (s, c) at phase 0 (beyond the state without one) */
    X[m + n + 1] = L->a_d;
    X[inverse_at(L)] = 0.0; /* a backlash inverse's correction: 0 until the play's first contact */
    if (state != NULL) { /* the whole loop state: the plant's coordinates, then z */
        snprintf(allowed, sizeof allowed, "the loop's state has %d plant coordinates %s and %d controller states", m,
                 cls->coordinates_text, n);
        rc = check_count(&err, "length of state", nstate, nstate == (size_t)(m + n), allowed);
        for (i = 0; rc == DFWB_OK && i < m; i++) {
            snprintf(allowed, sizeof allowed, "%s must be a finite number", cls->coordinates[i]);
            rc = dfwb_check(&err, cls->coordinates[i], state[i], 1, allowed);
        }
        if (rc == DFWB_OK && cls->check_state != NULL)
            rc = cls->check_state(L, state, &err);
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
    if (rc == DFWB_OK)
        rc = coulomb_fits(L, &err);
    if (rc != DFWB_OK) {
        free(L);
        return rc;
    }
    setup(L, section);
    if (L->has_inverse) /* a start on a wall of the play has touched it */
        contact(L, L->cls->wall(L, X), X);
    if (L->d > 0.0) { /* the deadband's side at t = 0 (of y + w) */
        const double y = X[L->out] + (L->has_inverse ? X[inverse_at(L)] : 0.0);
        set_band(L, fabs(y) < L->d ? 0 : y > 0.0 ? 1 : -1);
    }
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
int dfwb_loop_advance(dfwb_loop *p, double t_end, int stop_section, const unsigned int *stop_events,
                      long long *budget_left, long long budget_total, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_advance: NULL instance");
    return dfwb_err_finish(&err, dfwb_hy_advance(&p->hy, t_end, stop_section, stop_events, budget_left,
                                                     budget_total, &err));
}

int dfwb_loop_stopped(const dfwb_loop *p) { return p == NULL ? 0 : p->hy.stopped; }

/* FeedbackLoop.applied: the force on the plant at the solver's state X, the controller's, the feedforward of the
 * velocity in the current mode and the dither's, added in Python's order. */
static double applied(const dfwb_loop *p, const double *X)
{
    const double k = p->has_coulomb && p->F_hat != 0.0 ? p->F_hat * (double)p->cls->slip(p->hy.key) : 0.0;
    return dfwb_loop_feedback(p, X) + k + (p->has_dither ? X[p->m + p->order] : 0.0);
}

int dfwb_loop_sample(dfwb_loop *p, const double *times, size_t n, double *states, int *keys, double *forces,
                     long long *budget_left, long long budget_total, char *errbuf, size_t errlen)
{
    dfwb_err err;
    double X[DFWB_HY_DIM];
    size_t i, size;
    int rc = DFWB_OK;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL || (n > 0 && (times == NULL || states == NULL)))
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_sample: NULL argument");
    size = (size_t)(p->m + p->order);
    for (i = 0; i < n && rc == DFWB_OK; i++) {
        rc = dfwb_hy_advance(&p->hy, times[i], 0, NULL, budget_left, budget_total, &err);
        if (rc != DFWB_OK)
            break;
        dfwb_hy_state(&p->hy, X);
        memcpy(states + i * size, X, size * sizeof *X);
        if (keys != NULL)
            keys[i] = p->hy.key;
        if (forces != NULL)
            forces[i] = applied(p, X);
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
    double full[DFWB_HY_DIM];
    if (p != NULL && X != NULL) {
        dfwb_hy_state(&p->hy, full);
        memcpy(X, full, (size_t)(p->m + p->order) * sizeof *X);
    }
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
    return p == NULL || X == NULL ? NAN : dfwb_loop_feedback(p, X);
}

void dfwb_loop_parameters(const dfwb_loop *p, double out[DFWB_LOOP_PAR])
{
    int i;
    for (i = 0; i < DFWB_LOOP_PAR; i++)
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
    size_t i, k, width, size;
    if (p == NULL)
        return 0;
    if (t == NULL || X == NULL || max == 0)
        return p->hy.ncrossings;
    k = max < p->hy.ncrossings ? max : p->hy.ncrossings;
    width = (size_t)p->hy.n + 1;
    size = (size_t)(p->m + p->order); /* a dither's oscillator left out */
    for (i = 0; i < k; i++) {
        t[i] = p->hy.crossings[i * width];
        memcpy(X + i * size, p->hy.crossings + i * width + 1, size * sizeof *X);
    }
    if (k < p->hy.ncrossings)
        memmove(p->hy.crossings, p->hy.crossings + k * width, (p->hy.ncrossings - k) * width * sizeof(double));
    p->hy.ncrossings -= k;
    return k;
}

unsigned long long dfwb_loop_crossings_dropped(const dfwb_loop *p) { return p == NULL ? 0 : p->hy.crossings_dropped; }

/* The slots a loop may build: its mode keys at each side of its deadband (without one, at the one variant). */
static int slots_allowed(const dfwb_loop *p)
{
    const int keys = (1 << p->cls->keys) - 1;
    return p->d > 0.0 ? keys | keys << DFWB_HY_KEYS | keys << (2 * DFWB_HY_KEYS) : keys;
}

/* Build the mode of a slot (its key at its variant's side of the deadband), the current side kept. */
static int build_slot(dfwb_loop *p, int slot, dfwb_err *err)
{
    const int band = p->band, variant = slot / DFWB_HY_KEYS;
    int rc = DFWB_OK;
    set_band(p, variant == 0 ? 1 : variant == 1 ? 0 : -1);
    if (dfwb_hy_mode_of(&p->hy, slot % DFWB_HY_KEYS, err) == NULL)
        rc = err->code != DFWB_OK ? err->code : DFWB_E_MATH;
    set_band(p, band);
    return rc;
}

int dfwb_loop_band(const dfwb_loop *p) { return p == NULL ? 0 : p->band; }

void dfwb_loop_compensation(const dfwb_loop *p, double out[7])
{
    out[0] = p == NULL ? NAN : (double)p->has_coulomb;
    out[1] = p == NULL ? NAN : p->F_hat;
    out[2] = p == NULL ? NAN : (double)p->reset;
    out[3] = p == NULL ? NAN : p->d;
    out[4] = p == NULL ? NAN : p->a_d;
    out[5] = p == NULL ? NAN : p->w_d;
    out[6] = p == NULL ? NAN : p->h_hat;
}

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
    if (mask < 0 || (mask & ~slots_allowed(p)))
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_build_modes: modes %d are not the loop's", mask);
    for (i = 0; i < DFWB_HY_MODES && rc == DFWB_OK; i++)
        if ((mask >> i) & 1)
            rc = build_slot(p, i, &err);
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
        || a->hy.has_section != b->hy.has_section || !dfwb_same_double(a->section, b->section)
        || a->has_coulomb != b->has_coulomb || a->reset != b->reset || !dfwb_same_double(a->F_hat, b->F_hat)
        || !dfwb_same_double(a->d, b->d) || a->has_dither != b->has_dither || !dfwb_same_double(a->a_d, b->a_d)
        || !dfwb_same_double(a->w_d, b->w_d) || a->has_inverse != b->has_inverse
        || !dfwb_same_double(a->h_hat, b->h_hat))
        return 0;
    for (i = 0; i < DFWB_LOOP_PAR; i++)
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
    for (i = 0; i < DFWB_LOOP_STATE_PAR; i++)
        dfwb_io_f64(io, &L->par[i]);
    dfwb_io_int(io, &L->order);
    for (i = 0; i <= MAX_ORDER; i++)
        dfwb_io_f64(io, &L->bc[i]);
    for (i = 0; i < MAX_ORDER; i++)
        dfwb_io_f64(io, &L->ac[i]);
    dfwb_io_int(io, &hy->has_section);
    dfwb_io_f64(io, &L->section);
    dfwb_io_int(io, &L->has_coulomb);
    dfwb_io_f64(io, &L->F_hat);
    dfwb_io_int(io, &L->reset);
    dfwb_io_f64(io, &L->d);
    dfwb_io_int(io, &L->band);
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
    dfwb_io_f64(io, &hy->step_h);
    for (i = 0; i < DFWB_HY_DIM; i++) {
        dfwb_io_f64(io, &hy->X1[i]);
        dfwb_io_f64(io, &hy->dX1[i]);
        dfwb_io_f64(io, &hy->d20[i]);
        dfwb_io_f64(io, &hy->d21[i]);
        dfwb_io_f64(io, &hy->peak[i]);
    }
    dfwb_io_f64(io, &hy->next_h);
    dfwb_io_int(io, &L->has_dither); /* (last: the earlier fields keep their offsets) */
    dfwb_io_f64(io, &L->a_d);
    dfwb_io_f64(io, &L->w_d);
    dfwb_io_int(io, &L->has_inverse);
    dfwb_io_f64(io, &L->h_hat);
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
    dfwb_state_header(buf, DFWB_STATE_LOOP + p->plant, payload);
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
    double values[DFWB_LOOP_PARAMS_MAX] = {0.0}, q0[MAX_PLANT]; /* the constants, the initial values 0 */
    const dfwb_loop_class *cls = loop_plant_of(plant);
    int rc = DFWB_OK, mask = 0, i, n;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_from_bytes: NULL out");
    *out = NULL;
    if (cls == NULL || cls->nparams > DFWB_LOOP_PARAMS_MAX)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_loop_from_bytes: no plant kind %d", plant);
    rc = dfwb_state_open(buf, len, DFWB_STATE_LOOP + plant, loop_payload(), &err);
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
    L->cls = cls;
    L->plant = plant;
    L->m = cls->size;
    L->out = cls->out;
    /* the parameters and the controller, checked as dfwb_loop_new checks them: the constants the state holds
     * (a plant using fewer must hold 0 in the rest; the initial values, not state, as 0) */
    for (i = 0; i < DFWB_LOOP_STATE_PAR; i++)
        values[i] = s.par[i];
    for (i = cls->npar; rc == DFWB_OK && i < DFWB_LOOP_STATE_PAR; i++)
        if (s.par[i] != 0.0) {
            char name[32], allowed[64];
            snprintf(name, sizeof name, "parameter %d", i + 1);
            snprintf(allowed, sizeof allowed, "must be 0 (%s has %d)", cls->name, cls->npar);
            rc = dfwb_state_check(&err, name, s.par[i], 0, allowed);
        }
    dfwb_err_init(&local, message, sizeof message);
    if (rc == DFWB_OK && cls->check(L, values, q0, &local) != DFWB_OK)
        rc = state_refused(&err, "parameters", message);
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
    if (rc == DFWB_OK) /* the compensators, checked as dfwb_loop_new checks them */
        rc = dfwb_state_check_int(&err, "compensation flags", s.has_coulomb + 2 * s.reset, (s.has_coulomb == 0
                                  || s.has_coulomb == 1) && (s.reset == 0 || s.reset == 1), "must be 0 or 1");
    if (rc == DFWB_OK)
        rc = dfwb_state_check(&err, "F_hat", s.F_hat, s.has_coulomb || (s.F_hat == 0.0 && !signbit(s.F_hat)),
                              "must be 0 without a Coulomb feedforward");
    if (rc == DFWB_OK)
        rc = dfwb_state_check_int(&err, "dither flag", s.has_dither, s.has_dither == (s.a_d > 0.0),
                                  "must be 1 with a dither's amplitude above 0, else 0");
    if (rc == DFWB_OK)
        rc = dfwb_state_check(&err, "w_d", s.w_d, s.has_dither || (s.w_d == 0.0 && !signbit(s.w_d)),
                              "must be 0 without a dither");
    if (rc == DFWB_OK)
        rc = dfwb_state_check_int(&err, "backlash inverse flag", s.has_inverse, s.has_inverse == (s.h_hat > 0.0),
                                  "must be 1 with an estimated play above 0, else 0");
    if (rc == DFWB_OK) {
        const double compensation[7] = {(double)s.has_coulomb, s.F_hat, (double)s.reset, s.d, s.a_d, s.w_d,
                                        s.h_hat};
        if (compensators(L, compensation, s.ac, (size_t)n, &local) != DFWB_OK || coulomb_fits(L, &local) != DFWB_OK)
            rc = state_refused(&err, "compensators", message);
    }
    if (rc == DFWB_OK)
        rc = dfwb_state_check_int(&err, "deadband side", s.band, L->d > 0.0 ? -1 <= s.band && s.band <= 1
                                  : s.band == 1, "must be -1, 0 or 1 (1 without a deadband)");
    if (rc != DFWB_OK) {
        free(L);
        return rc;
    }
    setup(L, s.hy.has_section ? &s.section : NULL);
    set_band(L, s.band);
    if ((rc = dfwb_state_check(&err, "t", s.hy.t, isfinite(s.hy.t) && s.hy.t >= 0.0, "must be finite and >= 0"))
            != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "events", s.hy.events, s.hy.events >= 0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "count", s.count, s.count >= 0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "mode", s.hy.key, 0 <= s.hy.key && s.hy.key < cls->keys,
                                      "must be one of the plant's mode keys")) != DFWB_OK
        || (rc = dfwb_state_check_int(&err, "modes built", mask, 0 <= mask && !(mask & ~slots_allowed(L))
                                      && ((mask >> DFWB_HY_SLOT(&L->hy, s.hy.key)) & 1),
                                      "must be a set of modes with the current one")) != DFWB_OK) {
        dfwb_loop_free(L);
        return rc;
    }
    for (i = 0; i < DFWB_HY_MODES; i++)
        if (((mask >> i) & 1) && build_slot(L, i, &local) != DFWB_OK) {
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
    L->hy.step_h = s.hy.step_h;
    memcpy(L->hy.X1, s.hy.X1, sizeof L->hy.X1);
    memcpy(L->hy.dX1, s.hy.dX1, sizeof L->hy.dX1);
    memcpy(L->hy.d20, s.hy.d20, sizeof L->hy.d20);
    memcpy(L->hy.d21, s.hy.d21, sizeof L->hy.d21);
    memcpy(L->hy.peak, s.hy.peak, sizeof L->hy.peak);
    L->hy.next_h = s.hy.next_h;
    if (L->has_inverse) { /* the correction: 0 before the play's first touch, else a side's */
        const double w = L->hy.X[inverse_at(L)], half = L->cls->half_play(L) * L->h_hat;
        rc = dfwb_state_check(&err, "backlash inverse's correction", w, w == 0.0 || fabs(w) == half,
                              "must be 0 or +-h_hat/2 in the output's units, the side of the play's last touch");
    }
    if (rc == DFWB_OK)
        rc = dfwb_hy_resume(&L->hy, &err);
    if (rc == DFWB_OK && L->d > 0.0) { /* the side the output is on (to rounding: a state read at an edge) */
        double X[DFWB_HY_DIM], y;
        dfwb_hy_state(&L->hy, X);
        y = X[L->out] + (L->has_inverse ? X[inverse_at(L)] : 0.0); /* what the controller sees */
        rc = dfwb_state_check_int(&err, "deadband side", L->band, L->band == 0
                                  ? fabs(y) <= L->d * (1.0 + 1e-9) : (double)L->band * y >= L->d * (1.0 - 1e-9),
                                  "must be the output's: 0 within |y| < d, else the sign of y");
    }
    if (rc != DFWB_OK) {
        dfwb_loop_free(L);
        return rc;
    }
    *out = L;
    return DFWB_OK;
}
