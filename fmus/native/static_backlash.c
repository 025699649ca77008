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
#include <stddef.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "plant.h"

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

static const dfwb_static_backlash zero_state = {0}; /* the state's size is counted on it */

static const dfwb_plant_class STATIC_BACKLASH = {DFWB_PLANT_STATIC_BACKLASH, sizeof(dfwb_static_backlash),
                                                 &zero_state, offsetof(dfwb_static_backlash, mass), fire, restart,
                                                 state_io, validate};

int dfwb_static_backlash_check(dfwb_err *err, double M, double k, double h, double x0, double v0)
{
    int rc;
    if ((rc = dfwb_check(err, "M", M, M > 0.0, "M must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "k", k, k > 0.0, "k must be > 0")) != DFWB_OK
        || (rc = dfwb_check(err, "h", h, h > 0.0, "h must be > 0 (m)")) != DFWB_OK
        || (rc = dfwb_check(err, "x0", x0, 1, "x0 must be a finite number (m)")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "v0", v0, 1, "v0 must be a finite number (m/s)");
}

/* -- API ------------------------------------------------------------------------------------ */
int dfwb_static_backlash_new(const double params[DFWB_STATIC_BACKLASH_PARAMS], dfwb_static_backlash **out,
                             char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_static_backlash *p;
    void *plant;
    double M, k, h, F, omega, phi, x0, v0, f, harmonics;
    int rc;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL || params == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_static_backlash_new: NULL params or out");
    *out = NULL;
    M = params[DFWB_STATIC_BACKLASH_M], k = params[DFWB_STATIC_BACKLASH_k], h = params[DFWB_STATIC_BACKLASH_h];
    F = params[DFWB_STATIC_BACKLASH_F], omega = params[DFWB_STATIC_BACKLASH_omega];
    phi = params[DFWB_STATIC_BACKLASH_phi], x0 = params[DFWB_STATIC_BACKLASH_x0];
    v0 = params[DFWB_STATIC_BACKLASH_v0], f = params[DFWB_STATIC_BACKLASH_f];
    harmonics = params[DFWB_STATIC_BACKLASH_harmonics];
    if ((rc = dfwb_static_backlash_check(&err, M, k, h, x0, v0)) != DFWB_OK
        || (rc = dfwb_check_drive(&err, F, omega, phi, f, harmonics)) != DFWB_OK
        || (rc = dfwb_plant_alloc(&STATIC_BACKLASH, &plant, &err)) != DFWB_OK)
        return rc;
    p = (dfwb_static_backlash *)plant;
    dfwb_pw_init(&p->pw, F, omega, phi, f, harmonics);
    p->M = M, p->k = k, p->h = h;
    p->engaged = 0;
    rc = dfwb_plant_created(&p->pw, dfwb_err_finish(&err, free_play(p, 0.0, x0, v0, k * x0, 0, &err)), &plant);
    *out = (dfwb_static_backlash *)plant;
    return rc;
}

int dfwb_static_backlash_set_input(dfwb_static_backlash *p, double f, char *errbuf, size_t errlen)
{
    return dfwb_plant_set_input(&STATIC_BACKLASH, DFWB_PW(p), f, errbuf, errlen);
}

int dfwb_static_backlash_advance(dfwb_static_backlash *p, double t_end, char *errbuf, size_t errlen)
{
    return dfwb_plant_advance(&STATIC_BACKLASH, DFWB_PW(p), t_end, errbuf, errlen);
}

void dfwb_static_backlash_output(const dfwb_static_backlash *p, double out[3])
{
    double x, v, y, w;
    if (p == NULL || out == NULL)
        return;
    dfwb_motion_state(&p->mass, p->pw.t, &x, &v);
    dfwb_motion_state(&p->pw.output, p->pw.t, &y, &w);
    out[0] = x;
    out[1] = v;
    out[2] = y;
}

int dfwb_static_backlash_integrals(const dfwb_static_backlash *p, double *re, double *im, char *errbuf,
                                   size_t errlen)
{
    return dfwb_plant_integrals(&STATIC_BACKLASH, DFWB_PW(p), re, im, errbuf, errlen);
}

double dfwb_static_backlash_time(const dfwb_static_backlash *p) { return p == NULL ? NAN : p->pw.t; }

long long dfwb_static_backlash_events(const dfwb_static_backlash *p) { return p == NULL ? -1 : p->pw.events; }

int dfwb_static_backlash_harmonics(const dfwb_static_backlash *p) { return p == NULL ? -1 : p->pw.harmonics; }

double dfwb_static_backlash_period(const dfwb_static_backlash *p) { return p == NULL ? NAN : p->pw.period; }

void dfwb_static_backlash_drive(const dfwb_static_backlash *p, double out[4])
{
    if (p != NULL && out != NULL)
        dfwb_drive_values(&p->pw.drive, out);
}

int dfwb_static_backlash_engaged(const dfwb_static_backlash *p) { return p == NULL ? 0 : p->engaged; }

int dfwb_static_backlash_same_parameters(const dfwb_static_backlash *a, const dfwb_static_backlash *b)
{
    if (a == NULL || b == NULL)
        return 0;
    return dfwb_pw_same_parameters(&a->pw, &b->pw) && dfwb_same_double(a->M, b->M) && dfwb_same_double(a->k, b->k)
           && dfwb_same_double(a->h, b->h);
}

dfwb_static_backlash *dfwb_static_backlash_copy(const dfwb_static_backlash *p)
{
    return (dfwb_static_backlash *)dfwb_plant_copy(&STATIC_BACKLASH, DFWB_PW(p));
}

void dfwb_static_backlash_free(dfwb_static_backlash *p) { dfwb_plant_free(DFWB_PW(p)); }

void dfwb_static_backlash_log(dfwb_static_backlash *p, size_t capacity) { dfwb_plant_log(DFWB_PW(p), capacity); }

size_t dfwb_static_backlash_log_read(dfwb_static_backlash *p, double *t, int *kind, size_t max)
{
    return dfwb_plant_log_read(DFWB_PW(p), t, kind, max);
}

unsigned long long dfwb_static_backlash_log_dropped(const dfwb_static_backlash *p)
{
    return dfwb_plant_log_dropped(DFWB_PW(p));
}

int dfwb_static_backlash_to_bytes(const dfwb_static_backlash *p, unsigned char *buf, size_t buflen,
                                  size_t *size, char *errbuf, size_t errlen)
{
    return dfwb_plant_to_bytes(&STATIC_BACKLASH, DFWB_PW(p), buf, buflen, size, errbuf, errlen);
}

int dfwb_static_backlash_from_bytes(const unsigned char *buf, size_t len, dfwb_static_backlash **out,
                                    char *errbuf, size_t errlen)
{
    void *plant = NULL;
    const int rc = dfwb_plant_from_bytes(&STATIC_BACKLASH, buf, len, out == NULL ? NULL : &plant, errbuf, errlen);
    if (out != NULL)
        *out = (dfwb_static_backlash *)plant;
    return rc;
}
