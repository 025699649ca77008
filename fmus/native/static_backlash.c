/* static_backlash.c - a mass followed by the geometric backlash element, integrated exactly: a port of
 * fmus/static_backlash.py (StaticBacklash) on the piece machinery of plant.c. API: dfwb_core.h.
 *
 * M x'' = u(t) gives the input x of a play of slope k and total width h: y / k stays within
 * [x - h/2, x + h/2] and moves only when x drags it. Engagement (x reaching y/k +- h/2) is a first zero
 * of the closed-form position; disengagement is the velocity reversal, a first zero of the closed-form
 * velocity. Leaving an edge, x cannot return to it before -s v falls back to zero: that apex is searched
 * first (an uncounted event). The output is y; it starts centred, y = k x0.
 */
#include <math.h>
#include <stdio.h>
#include <stddef.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "loop.h"
#include "plant.h"

typedef struct dfwb_static_backlash dfwb_static_backlash;

struct dfwb_static_backlash {
    dfwb_pw pw; /* first: the piece machinery (its output is y) */
    double M, k, h;
    int engaged, leaving;
    double y;           /* y held while free */
    dfwb_motion mass;   /* the mass (the searches' subject) */
};

static void mass_motion(const dfwb_static_backlash *p, dfwb_motion *m, double t, double x, double v)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion_init(m, t, x, v, 0.0, d->f / p->M, d->F / p->M, d->omega, d->phi);
}

static void edge_searches(dfwb_static_backlash *p, double t, int skip)
{
    const double K = fabs(p->mass.a) + fabs(p->mass.b);
    int s;
    for (s = 1; s >= -1; s -= 2) { /* (1, -1) */
        double edge;
        if (s == skip)
            continue;
        edge = p->y / p->k + (double)s * 0.5 * p->h; /* s (edge - x), -s v */
        dfwb_pw_add_search(&p->pw, DFWB_SEARCH_EDGE, (double)s, 1, edge, K, 0, t,
                           s > 0 ? DFWB_EVENT_ENGAGE_UP : DFWB_EVENT_ENGAGE_DOWN);
    }
}

/* y held; x moves inside the play. leaving: the edge just left (+-1). */
static int free_play(dfwb_static_backlash *p, double t, double x, double v, double y, int leaving, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion out;
    p->engaged = 0;
    p->leaving = leaving;
    p->y = y;
    mass_motion(p, &p->mass, t, x, v);
    dfwb_motion_init(&out, t, y, 0.0, 0.0, 0.0, 0.0, d->omega, d->phi);
    dfwb_pw_begin(&p->pw, t, &out, INFINITY, 0);
    edge_searches(p, t, leaving);
    if (leaving) { /* x cannot return to the edge it left before -s v falls back to zero */
        double t_from = t, K;
        if (!(-(double)leaving * v > 0.0)) {
            const int rc = dfwb_drive_crossing(d, t, 0.0, leaving > 0, &t_from, err);
            if (rc != DFWB_OK)
                return rc;
        }
        K = dfwb_motion_curvature_bound(&p->mass, 0, 0.0, err);
        dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, -(double)leaving, 0, 0.0, K, 0, t_from, DFWB_EVENT_APEX);
    }
    return DFWB_OK;
}

/* x drags y: y = k (x - s h/2) until the velocity reverses. */
static int engage(dfwb_static_backlash *p, double t, double x, double v, int s, dfwb_err *err)
{
    const double shift = (double)s * 0.5 * p->h, k = p->k;
    dfwb_motion out;
    double t_from = t, K;
    p->engaged = s;
    mass_motion(p, &p->mass, t, x, v);
    dfwb_motion_init(&out, t, k * (x - shift), k * v, 0.0, k * p->mass.a, k * p->mass.b, p->mass.omega,
                     p->mass.phi);
    if (!((double)s * v > 0.0)) {
        const int rc = dfwb_drive_crossing(&p->pw.drive, t, 0.0, s < 0, &t_from, err);
        if (rc != DFWB_OK)
            return rc;
    }
    K = dfwb_motion_curvature_bound(&p->mass, 0, 0.0, err);
    dfwb_pw_begin(&p->pw, t, &out, INFINITY, 0);
    dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, (double)s, 0, 0.0, K, 0, t_from, DFWB_EVENT_REVERSE); /* s v */
    return DFWB_OK;
}

static int fire(void *plant, double t, int kind, int *counted, dfwb_err *err)
{
    dfwb_static_backlash *p = (dfwb_static_backlash *)plant;
    double x, v;
    if (kind == DFWB_EVENT_APEX) {
        p->leaving = 0;
        dfwb_pw_set_searches(&p->pw, t);
        edge_searches(p, t, 0);
        *counted = 0;
        return DFWB_OK;
    }
    dfwb_motion_state(&p->mass, t, &x, &v);
    dfwb_pw_close_piece(&p->pw, t, err);
    *counted = 1;
    /* x and v stay as computed (no snapping): the mass's motion is continuous */
    if (kind == DFWB_EVENT_REVERSE) {
        const int s = p->engaged;
        return free_play(p, t, x, v, p->k * (x - (double)s * 0.5 * p->h), s, err);
    }
    return engage(p, t, x, v, kind == DFWB_EVENT_ENGAGE_UP ? 1 : -1, err);
}

/* the new force drives x into that edge just after t */
static int pushing(const dfwb_static_backlash *p, double t, int edge)
{
    return edge > 0 ? dfwb_drive_above(&p->pw.drive, t, 0.0) : dfwb_drive_below(&p->pw.drive, t, 0.0);
}

static int restart(void *plant, double t, dfwb_err *err)
{
    dfwb_static_backlash *p = (dfwb_static_backlash *)plant;
    const int s = p->engaged;
    double x, v;
    dfwb_motion_state(&p->mass, t, &x, &v);
    if (s && (double)s * v <= 0.0 && !pushing(p, t, s)) {
        /* at rest on the edge with the new force not pushing on: it lets go of y */
        double y, w;
        dfwb_motion_state(&p->pw.output, t, &y, &w);
        return free_play(p, t, x, v, y, s, err);
    }
    if (s)
        return engage(p, t, x, v, s, err);
    if (p->leaving && -(double)p->leaving * v <= 0.0 && pushing(p, t, p->leaving))
        /* still on the edge it was leaving, and the new force pushes back: it drags y again */
        return engage(p, t, x, v, p->leaving, err);
    return free_play(p, t, x, v, p->y, p->leaving, err);
}

/* -- state as bytes ---------------------------------------------------------------------------- */
static void state_io(dfwb_io *io, void *plant)
{
    dfwb_static_backlash *p = (dfwb_static_backlash *)plant;
    dfwb_pw_io(io, &p->pw);
    dfwb_io_f64(io, &p->M);
    dfwb_io_f64(io, &p->k);
    dfwb_io_f64(io, &p->h);
    dfwb_io_int(io, &p->engaged);
    dfwb_io_int(io, &p->leaving);
    dfwb_io_f64(io, &p->y);
    dfwb_io_motion(io, &p->mass);
}

static int validate(void *plant, dfwb_err *err)
{
    dfwb_static_backlash *p = (dfwb_static_backlash *)plant;
    const dfwb_pw *pw = &p->pw;
    int rc, i;
    if ((rc = dfwb_state_check(err, "M", p->M, isfinite(p->M) && p->M > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "k", p->k, isfinite(p->k) && p->k > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "h", p->h, isfinite(p->h) && p->h > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "engaged", p->engaged, -1 <= p->engaged && p->engaged <= 1,
                                      "must be -1, 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "leaving", p->leaving, -1 <= p->leaving && p->leaving <= 1,
                                      "must be -1, 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check(err, "y", p->y, isfinite(p->y), "must be finite")) != DFWB_OK
        || (rc = dfwb_state_motion(&p->mass, "mass", &pw->drive, pw->t, err)) != DFWB_OK)
        return rc;
    if (pw->output.lam != 0.0 || p->mass.lam != 0.0)
        return dfwb_fail(err, DFWB_E_STATE, "the state's motions are out of range: a static backlash has no damping");
    if (!(pw->analytic_kind == 0 && isinf(pw->analytic)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's piece is out of range: it has no analytic event");
    for (i = 0; i < pw->nsearch; i++) {
        const dfwb_search *s = &pw->searches[i];
        int ok;
        switch (s->kind) {
        case DFWB_EVENT_ENGAGE_UP:
        case DFWB_EVENT_ENGAGE_DOWN:
            ok = s->type == DFWB_SEARCH_EDGE && s->has_level
                 && s->sign == (s->kind == DFWB_EVENT_ENGAGE_UP ? 1.0 : -1.0) && p->engaged == 0;
            break;
        case DFWB_EVENT_APEX:
            ok = s->type == DFWB_SEARCH_VELOCITY && !s->has_level && p->engaged == 0;
            break;
        case DFWB_EVENT_REVERSE:
            ok = s->type == DFWB_SEARCH_VELOCITY && !s->has_level && p->engaged != 0
                 && s->sign == (double)p->engaged;
            break;
        default:
            ok = 0;
        }
        if (!ok || s->bounded)
            return dfwb_fail(err, DFWB_E_STATE, "the state's search %d (kind %d) is out of range: not a search "
                             "of a %s piece", i, s->kind, p->engaged ? "engaged" : "free");
    }
    return DFWB_OK;
}

/* The parameter checks, in the Python check's order: shared by the plant and its closed loop. */
static int check_parameters(dfwb_err *err, double M, double k, double h, double x0, double v0)
{
    int rc;
    if ((rc = dfwb_check(err, "M", M, M > 0.0, "M must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "k", k, k > 0.0, "k must be > 0")) != DFWB_OK
        || (rc = dfwb_check(err, "h", h, h > 0.0, "h must be > 0 (m)")) != DFWB_OK
        || (rc = dfwb_check(err, "x0", x0, 1, "x0 must be a finite number (m)")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "v0", v0, 1, "v0 must be a finite number (m/s)");
}

/* -- the closed loop (StaticBacklashLoop of fmus/static_backlash.py): q = (x, v, y), y = q[2] ---------------------- */
/* StaticBacklashLoop.__init__: {M, k, h, x0, v0}; par = {M, k, h}; y starts centred, k x0 */
static int loop_check(dfwb_loop *L, const double *v, double *q0, dfwb_err *err)
{
    const double M = v[DFWB_STATIC_BACKLASH_LOOP_M], k = v[DFWB_STATIC_BACKLASH_LOOP_k];
    const double h = v[DFWB_STATIC_BACKLASH_LOOP_h], x0 = v[DFWB_STATIC_BACKLASH_LOOP_x0];
    const double v0 = v[DFWB_STATIC_BACKLASH_LOOP_v0];
    int rc;
    if ((rc = check_parameters(err, M, k, h, x0, v0)) != DFWB_OK)
        return rc;
    L->par[0] = M;
    L->par[1] = k;
    L->par[2] = h;
    q0[0] = x0;
    q0[1] = v0;
    q0[2] = k * x0;
    return DFWB_OK;
}

/* StaticBacklashLoop.check_coordinates */
static int loop_check_state(const dfwb_loop *L, const double *q, dfwb_err *err)
{
    const double play = q[0] - q[2] / L->par[1];
    char rh[DFWB_REPR_SIZE], allowed[96];
    dfwb_repr(0.5 * L->par[2], rh);
    snprintf(allowed, sizeof allowed, "the play x - y/k must be within +-h/2 = %s (m)", rh);
    return dfwb_check(err, "x - y/k", play, fabs(play) <= 0.5 * L->par[2] * (1.0 + 1e-9), allowed);
}

/* StaticBacklashLoop.plant_mode */
static void loop_mode(const dfwb_loop *L, int key, dfwb_plant_mode *pm)
{
    const double M = L->par[0], k = L->par[1], half = 0.5 * L->par[2];
    pm->P[0][1] = 1.0;
    pm->phi[1] = 1.0 / M;
    if (key == DFWB_LOOP_FREE) {
        dfwb_loop_add_event(pm, DFWB_EVENT_ENGAGE_UP, -1.0, 0.0, 1.0 / k, 0.0, 0.0, half); /* y/k + h/2 - x > 0 */
        dfwb_loop_add_event(pm, DFWB_EVENT_ENGAGE_DOWN, 1.0, 0.0, -1.0 / k, 0.0, 0.0, half); /* x - y/k + h/2 > 0 */
        return;
    }
    pm->P[2][1] = k;
    dfwb_loop_add_event(pm, DFWB_EVENT_REVERSE, 0.0, key == DFWB_LOOP_ENGAGED_UP ? 1.0 : -1.0, 0.0, 0.0, 0.0,
                        0.0); /* s v > 0 */
}

/* StaticBacklashLoop._engage */
static int loop_engage(dfwb_loop *L, int s, double *X, int count, int *key, int *departing, dfwb_err *err)
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

/* StaticBacklashLoop.wall: the edge of the play X sits on to rounding (initial snaps it there), else 0 */
static int loop_wall(const dfwb_loop *L, const double *X)
{
    const double play = X[0] - X[2] / L->par[1], edge = 0.5 * L->par[2] * (1.0 - 1e-12);
    return play >= edge ? 1 : -play >= edge ? -1 : 0;
}

static int loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    const int s = loop_wall(L, X); /* on an edge: engaged if moving on */
    if (!s) {
        *key = DFWB_LOOP_FREE;
        return DFWB_OK;
    }
    X[0] = X[2] / L->par[1] + (double)s * 0.5 * L->par[2]; /* on the edge, the given output kept */
    return loop_engage(L, s, X, 0, key, departing, err);
}

static int loop_fire(dfwb_loop *L, int kind, double *X, int *key, int *departing, dfwb_err *err)
{
    if (kind == DFWB_EVENT_REVERSE) {
        const int s = L->hy.key == DFWB_LOOP_ENGAGED_UP ? 1 : -1;
        X[1] = 0.0;
        *key = DFWB_LOOP_FREE;
        *departing = s > 0 ? 0 : 1;
        return DFWB_OK;
    }
    return loop_engage(L, kind == DFWB_EVENT_ENGAGE_UP ? 1 : -1, X, 1, key, departing, err);
}

/* StaticBacklashLoop.CONTACTS and half_play: x reaches the upper / lower edge; k / 2 */
static int loop_contact(int kind)
{
    return kind == DFWB_EVENT_ENGAGE_UP ? 1 : kind == DFWB_EVENT_ENGAGE_DOWN ? -1 : 0;
}

static double loop_half_play(const dfwb_loop *L) { return 0.5 * L->par[1]; }

static const char *const LOOP_COORDINATES[] = {"x", "v", "y"};

static const dfwb_loop_class LOOP = {3, 2, DFWB_LOOP_STATIC_BACKLASH_PARAMS, 3, "a static backlash",
                                                   LOOP_COORDINATES, "('x', 'v', 'y')", loop_check, loop_check_state,
                                                   loop_mode, loop_initial, loop_fire, 3, NULL, NULL, -1, NULL, 0,
                                                   "StaticBacklashLoop", loop_contact, loop_wall,
                                                   loop_half_play};

/* -- the class ------------------------------------------------------------------------------------ */
/* StaticBacklash.__init__, then PiecewisePlant's: the order of the Python constructor */
static int init(void *plant, const double *params, dfwb_err *err)
{
    dfwb_static_backlash *p = (dfwb_static_backlash *)plant;
    const double M = params[DFWB_STATIC_BACKLASH_M], k = params[DFWB_STATIC_BACKLASH_k];
    const double h = params[DFWB_STATIC_BACKLASH_h], F = params[DFWB_STATIC_BACKLASH_F];
    const double omega = params[DFWB_STATIC_BACKLASH_omega], phi = params[DFWB_STATIC_BACKLASH_phi];
    const double x0 = params[DFWB_STATIC_BACKLASH_x0], v0 = params[DFWB_STATIC_BACKLASH_v0];
    const double f = params[DFWB_STATIC_BACKLASH_f], harmonics = params[DFWB_STATIC_BACKLASH_harmonics];
    int rc;
    if ((rc = check_parameters(err, M, k, h, x0, v0)) != DFWB_OK
        || (rc = dfwb_check_drive(err, F, omega, phi, f, harmonics)) != DFWB_OK)
        return rc;
    dfwb_pw_init(&p->pw, F, omega, phi, f, harmonics);
    p->M = M, p->k = k, p->h = h;
    p->engaged = 0;
    return dfwb_err_finish(err, free_play(p, 0.0, x0, v0, k * x0, 0, err));
}

/* {x, v, y} */
static void output(const void *plant, double *out)
{
    const dfwb_static_backlash *p = (const dfwb_static_backlash *)plant;
    double x, v, y, w;
    dfwb_motion_state(&p->mass, p->pw.t, &x, &v);
    dfwb_motion_state(&p->pw.output, p->pw.t, &y, &w);
    out[0] = x;
    out[1] = v;
    out[2] = y;
}

/* 0 engaged (0 free, +1/-1 at the upper/lower edge of the play) */
static long long counter(const void *plant, size_t i)
{
    (void)i;
    return ((const dfwb_static_backlash *)plant)->engaged;
}

static int same(const void *one, const void *other)
{
    const dfwb_static_backlash *a = (const dfwb_static_backlash *)one, *b = (const dfwb_static_backlash *)other;
    return dfwb_same_double(a->M, b->M) && dfwb_same_double(a->k, b->k) && dfwb_same_double(a->h, b->h);
}

static const dfwb_static_backlash zero_state = {0}; /* the state's size is counted on it */

const dfwb_plant_class dfwb_static_backlash_class = {
    DFWB_PLANT_STATIC_BACKLASH, sizeof(dfwb_static_backlash), &zero_state, offsetof(dfwb_static_backlash, mass),
    fire, restart, state_io, validate, DFWB_STATIC_BACKLASH_PARAMS, 3, 1, init, output, counter, same,
    &LOOP, NULL, NULL, NULL, NULL};
