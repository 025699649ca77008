/* friction.c - the friction mass, integrated exactly: a port of fmus/piecewise.py (PiecewisePlant) and
 * fmus/friction.py (FrictionMass). The API is documented in dfwb_core.h.
 *
 * A run is a sequence of pieces. A piece holds the closed-form motion of the mass and its next event:
 * an analytic instant (the force crossing a level: break-away, release) or the first zero of the
 * velocity's distance to the band (a search, run lazily in chunks of period/8 anchored at the piece's
 * start, never at the communication points, so the result does not depend on how an importer steps).
 * The Fourier integrals of x are accumulated piece by piece in closed form.
 *
 * Modes: hold (v constant, |v| <= Dv), push +-1 (inside the band, |u| > Fs), slide +-1.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "plant.h"

enum { HOLD, SLIDE, PUSH };

/* EventKind (fmus/contract.py, DFWB_EVENT_*); NONE: a piece without an analytic event */
enum {
    KIND_NONE = 0,
    BREAK_UP = DFWB_EVENT_BREAK_UP,
    BREAK_DOWN = DFWB_EVENT_BREAK_DOWN,
    RELEASE = DFWB_EVENT_RELEASE,
    EDGE = DFWB_EVENT_EDGE,
    BAND = DFWB_EVENT_BAND
};

/* A pending search on the piece's own motion: VelocitySearch(motion, sign, offset) with the bound
 * K (a number) or, when ``bounded``, CurvatureBound(motion) (a function of t). */
typedef struct {
    double sign, offset; /* g = offset + sign v, g' = sign v' */
    int bounded;
    double K;
    double t_from;
    int kind;
} search_t;

struct dfwb_friction {
    double M, B, Fc, Fs, Dv, edge_force;
    dfwb_drive drive;
    double period;
    int harmonics;
    double t;
    long long events;
    int mode, direction;
    /* the piece */
    double t_piece;
    dfwb_motion output;
    double analytic;
    int analytic_kind;
    int nsearch; /* 0 or 1 */
    search_t search;
    double searched;
    int has_found;
    double found_t;
    int found_kind;
    dfwb_cx integrals[DFWB_HARMONICS_MAX + 1];
    dfwb_stack stack; /* first_root's workspace (not copied) */
    dfwb_log log;     /* the caller's event log (not state) */
};

/* the search functions on the piece's motion (ctx: the instance) */
static void velocity_search(const void *ctx, double t, double *g, double *dg)
{
    const dfwb_friction *p = (const dfwb_friction *)ctx;
    const double v = dfwb_motion_velocity(&p->output, t);
    *g = p->search.offset + p->search.sign * v;
    *dg = p->search.sign * dfwb_motion_acceleration(&p->output, t, v);
}

static double curvature_bound(const void *ctx, double t, dfwb_err *err)
{
    return dfwb_motion_curvature_bound(&((const dfwb_friction *)ctx)->output, 1, t, err);
}

#define err_init dfwb_err_init
#define err_finish dfwb_err_finish
#define check dfwb_check

/* -- pieces ------------------------------------------------------------------------------- */
static void begin(dfwb_friction *p, double t, double analytic, int analytic_kind)
{
    p->t_piece = t;
    p->analytic = analytic;
    p->analytic_kind = analytic_kind;
    p->searched = t;
    p->has_found = 0;
}

/* _motion: the mass under a constant force plus the drive's harmonic part, damped by lam */
static void mass_motion(const dfwb_friction *p, dfwb_motion *m, double t, double x, double v, double lam,
                        double force)
{
    const dfwb_drive *d = &p->drive;
    dfwb_motion_init(m, t, x, v, lam, force / p->M, d->F / p->M, d->omega, d->phi);
}

/* Velocity held inside the band (stick when Dv = 0) while |u| is small. */
static int hold(dfwb_friction *p, double t, double x, double v, dfwb_err *err)
{
    double up, down, t_up, t_down;
    int rc;
    p->mode = HOLD;
    p->direction = 0;
    up = v >= p->Dv ? (p->edge_force > p->Fs ? p->edge_force : p->Fs) : p->Fs;
    down = v <= -p->Dv ? (p->edge_force > p->Fs ? p->edge_force : p->Fs) : p->Fs;
    rc = dfwb_drive_crossing(&p->drive, t, up, 1, &t_up, err);
    if (rc != DFWB_OK)
        return rc;
    rc = dfwb_drive_crossing(&p->drive, t, -down, 0, &t_down, err);
    if (rc != DFWB_OK)
        return rc;
    dfwb_motion_init(&p->output, t, x, v, 0.0, 0.0, 0.0, p->drive.omega, p->drive.phi);
    p->nsearch = 0;
    if (t_up <= t_down)
        begin(p, t, t_up, BREAK_UP);
    else
        begin(p, t, t_down, BREAK_DOWN);
    return DFWB_OK;
}

/* Inside the band with |u| > Fs: friction Fs opposes u, v moves towards s * Dv. */
static int push(dfwb_friction *p, double t, double x, double v, int s, dfwb_err *err)
{
    dfwb_motion motion;
    double t_release;
    int rc;
    p->mode = PUSH;
    p->direction = s;
    mass_motion(p, &motion, t, x, v, 0.0, p->drive.f - (double)s * p->Fs);
    rc = dfwb_drive_crossing(&p->drive, t, (double)s * p->Fs, s < 0, &t_release, err);
    if (rc != DFWB_OK)
        return rc;
    p->output = motion;
    p->nsearch = 1; /* gap to the edge: Dv - s v, -s v' */
    p->search.sign = (double)(-s);
    p->search.offset = p->Dv;
    p->search.bounded = 0;
    p->search.K = dfwb_motion_curvature_bound(&motion, 0, 0.0, err);
    p->search.t_from = t;
    p->search.kind = EDGE;
    begin(p, t, t_release, RELEASE);
    return DFWB_OK;
}

/* Sliding in direction s until the velocity falls back to the band. */
static int slide(dfwb_friction *p, double t, double x, double v, int s, int departing, dfwb_err *err)
{
    dfwb_motion motion;
    double t_from = t;
    int rc;
    p->mode = SLIDE;
    p->direction = s;
    mass_motion(p, &motion, t, x, v, p->B / p->M, p->drive.f - (double)s * p->Fc);
    if (departing) { /* leaving the band edge, s*v - Dv > 0 is proven while s*u > Fc + B Dv */
        rc = dfwb_drive_crossing(&p->drive, t, (double)s * p->edge_force, s < 0, &t_from, err);
        if (rc != DFWB_OK)
            return rc;
    }
    p->output = motion;
    p->nsearch = 1; /* speed above the band: s v - Dv, s v' */
    p->search.sign = (double)s;
    p->search.offset = -p->Dv;
    /* with damping, K is a function of t: the initial velocity's part of v'' decays */
    p->search.bounded = p->B != 0.0;
    p->search.K = p->search.bounded ? 0.0 : dfwb_motion_curvature_bound(&motion, 0, 0.0, err);
    p->search.t_from = t_from;
    p->search.kind = BAND;
    begin(p, t, INFINITY, KIND_NONE);
    return DFWB_OK;
}

/* Choose the mode from the state and the force at t; at_edge = s when v has just reached the band
 * edge s * Dv (up to rounding). The state stays continuous across the switch. */
static int start(dfwb_friction *p, double t, double x, double v, int at_edge, dfwb_err *err)
{
    const double Dv = p->Dv;
    const dfwb_drive *d = &p->drive;
    int point_band, upper, lower;
    double breakaway;
    if (!at_edge && fabs(v) > Dv)
        return slide(p, t, x, v, v > 0.0 ? 1 : -1, 0, err);
    point_band = Dv == 0.0 && at_edge != 0; /* both edges are v = 0 */
    upper = at_edge == 1 || v >= Dv || point_band;
    lower = at_edge == -1 || v <= -Dv || point_band;
    breakaway = p->edge_force > p->Fs ? p->edge_force : p->Fs; /* max(Fs, edge_force) */
    if (upper && dfwb_drive_above(d, t, breakaway))
        return slide(p, t, x, Dv == 0.0 ? v : Dv, 1, 1, err);
    if (lower && dfwb_drive_below(d, t, -breakaway))
        return slide(p, t, x, Dv == 0.0 ? v : -Dv, -1, 1, err);
    if (!upper && dfwb_drive_above(d, t, p->Fs))
        return push(p, t, x, v, 1, err);
    if (!lower && dfwb_drive_below(d, t, -p->Fs))
        return push(p, t, x, v, -1, err);
    return hold(p, t, x, at_edge ? (double)at_edge * Dv : v, err);
}

/* End of the search chunk containing t: a grid of period/8 anchored at the piece start. */
static int chunk_end(const dfwb_friction *p, double t, double *end, dfwb_err *err)
{
    const double width = p->period / 8.0;
    const double n = floor((t - p->t_piece) / width) + 1.0;
    char rt[DFWB_REPR_SIZE], rw[DFWB_REPR_SIZE];
    *end = p->t_piece + n * width;
    if (!(*end > t)) {
        *end = t + width;
        if (!(*end > t)) { /* the search would not advance */
            dfwb_repr(t, rt);
            dfwb_repr(width, rw);
            return dfwb_fail(err, DFWB_E_LIMIT,
                             "t = %s is out of range: a search chunk of %s s does not advance past it", rt, rw);
        }
    }
    return DFWB_OK;
}

/* The piece's next event if it is <= t_end (*has = 1), searching chunk by chunk up to it. */
static int next_event(dfwb_friction *p, double t_end, int *has, double *t_event, int *kind, dfwb_err *err)
{
    double event_t;
    int event_kind, rc;
    while (!p->has_found && p->searched < (t_end < p->analytic ? t_end : p->analytic)) {
        const double a = p->searched;
        double b;
        rc = chunk_end(p, a, &b, err);
        if (rc != DFWB_OK)
            return rc;
        if (p->analytic < b)
            b = p->analytic;
        if (p->nsearch) {
            const double lo = p->search.t_from > a ? p->search.t_from : a;
            if (lo < b) {
                int found;
                double root;
                rc = dfwb_first_root(velocity_search, p->search.bounded ? curvature_bound : NULL, p, lo, b,
                                     p->search.K, &p->stack, &found, &root, err);
                if (rc != DFWB_OK)
                    return rc;
                if (found && (!p->has_found || root < p->found_t)) {
                    p->has_found = 1;
                    p->found_t = root;
                    p->found_kind = p->search.kind;
                }
            }
        }
        p->searched = b;
    }
    if (!p->has_found || p->analytic <= p->found_t) {
        event_t = p->analytic;
        event_kind = p->analytic_kind;
    } else {
        event_t = p->found_t;
        event_kind = p->found_kind;
    }
    *has = event_t <= t_end;
    *t_event = event_t;
    *kind = event_kind;
    return DFWB_OK;
}

/* The piece's Fourier integrals from its start to t: out[0] = int x, out[k] = int x exp(-i k w s). */
static void piece_integrals(const dfwb_friction *p, double t, dfwb_cx *out, dfwb_err *err)
{
    const dfwb_motion *m = &p->output;
    double x, v;
    int k;
    if (t <= m->t0) {
        for (k = 0; k <= p->harmonics; k++)
            out[k] = dfwb_cx_make(0.0, 0.0);
        return;
    }
    dfwb_motion_state(m, t, &x, &v);
    out[0] = dfwb_cx_real(dfwb_motion_integral(m, t, err));
    dfwb_motion_fourier(m, t, p->harmonics, x, v, out + 1);
}

static void close_piece(dfwb_friction *p, double t, dfwb_err *err)
{
    dfwb_cx piece[DFWB_HARMONICS_MAX + 1];
    int k;
    piece_integrals(p, t, piece, err);
    for (k = 0; k <= p->harmonics; k++)
        p->integrals[k] = dfwb_cx_add(p->integrals[k], piece[k]);
}

/* -- events ---------------------------------------------------------------------------- */
static int fire(dfwb_friction *p, double t, int kind, dfwb_err *err)
{
    double x, v;
    int s = p->direction;
    close_piece(p, t, err);
    dfwb_motion_state(&p->output, t, &x, &v);
    switch (kind) {
    case BREAK_UP:
    case BREAK_DOWN:
        s = kind == BREAK_UP ? 1 : -1;
        if ((double)s * v >= p->Dv)
            return slide(p, t, x, (double)s * p->Dv, s, 1, err);
        return push(p, t, x, v, s, err);
    case RELEASE: /* |u| falls to Fs: hold, or (Fs = 0) a push the other way */
        return start(p, t, x, v, 0, err);
    case EDGE: { /* pushed through the band to its edge s * Dv (Dv > 0) */
        const double edge = (double)s * p->edge_force;
        if (s > 0 ? dfwb_drive_above(&p->drive, t, edge) : dfwb_drive_below(&p->drive, t, edge))
            return slide(p, t, x, (double)s * p->Dv, s, 1, err);
        return hold(p, t, x, (double)s * p->Dv, err);
    }
    default: /* BAND: the sliding velocity reached the band edge */
        return start(p, t, x, v, s, err);
    }
}

static int restart(dfwb_friction *p, double t, dfwb_err *err)
{
    double x, v;
    int at_edge;
    dfwb_motion_state(&p->output, t, &x, &v);
    at_edge = p->mode == SLIDE && fabs(v) <= p->Dv ? p->direction : 0;
    return start(p, t, x, v, at_edge, err);
}

/* -- API ------------------------------------------------------------------------------------ */
int dfwb_core_abi_version(void) { return DFWB_CORE_ABI; }

int dfwb_friction_new(const double params[DFWB_FRICTION_PARAMS], dfwb_friction **out, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_friction *p;
    double M, B, Fc, Fs, Dv, F, omega, phi, x0, v0, f, harmonics;
    char rFc[DFWB_REPR_SIZE], allowed[96];
    int rc, k;
    err_init(&err, errbuf, errlen);
    if (out == NULL || params == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_new: NULL params or out");
    *out = NULL;
    M = params[0], B = params[1], Fc = params[2], Fs = params[3], Dv = params[4], F = params[5];
    omega = params[6], phi = params[7], x0 = params[8], v0 = params[9], f = params[10], harmonics = params[11];
    strcpy(allowed, "Fs must be >= Fc = ");
    if (!(isfinite(Fs) && Fs >= Fc)) { /* the message is written only when refused */
        dfwb_repr(Fc, rFc);
        strcat(allowed, rFc);
        strcat(allowed, " (N)");
    }
    /* FrictionMass, then PiecewisePlant: the order of the Python constructor */
    if ((rc = check(&err, "M", M, M > 0.0, "M must be > 0 (kg)")) != DFWB_OK
        || (rc = check(&err, "B", B, B >= 0.0, "B must be >= 0 (N.s/m)")) != DFWB_OK
        || (rc = check(&err, "Fc", Fc, Fc >= 0.0, "Fc must be >= 0 (N)")) != DFWB_OK
        || (rc = check(&err, "Fs", Fs, Fs >= Fc, allowed)) != DFWB_OK
        || (rc = check(&err, "Dv", Dv, Dv >= 0.0, "Dv must be >= 0 (m/s)")) != DFWB_OK
        || (rc = check(&err, "x0", x0, 1, "x0 must be a finite number (m)")) != DFWB_OK
        || (rc = check(&err, "v0", v0, 1, "v0 must be a finite number (m/s)")) != DFWB_OK
        || (rc = check(&err, "F", F, 1, "F must be a finite number (N)")) != DFWB_OK
        || (rc = check(&err, "omega", omega, omega > 0.0, "omega must be > 0 (rad/s)")) != DFWB_OK
        || (rc = check(&err, "phi", phi, fabs(phi) <= DFWB_PHASE_LIMIT,
                       "phi must be in [-" DFWB_PHASE_LIMIT_TEXT ", " DFWB_PHASE_LIMIT_TEXT
                       "] rad (beyond, a float does not resolve a period)")) != DFWB_OK
        || (rc = check(&err, "f", f, 1, "the input f must be a finite number (N)")) != DFWB_OK
        || (rc = check(&err, "harmonics", harmonics,
                       floor(harmonics) == harmonics && 0.0 <= harmonics && harmonics <= 10.0,
                       "harmonics must be an integer in 0..10")) != DFWB_OK)
        return rc;
    p = (dfwb_friction *)calloc(1, sizeof *p);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_MEMORY, "out of memory (a dfwb_friction)");
    dfwb_drive_init(&p->drive, f, F, omega, phi);
    p->period = DFWB_TWO_PI / omega;
    p->harmonics = (int)harmonics;
    p->t = 0.0;
    p->events = 0;
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++)
        p->integrals[k] = dfwb_cx_make(0.0, 0.0);
    p->M = M, p->B = B, p->Fc = Fc, p->Fs = Fs, p->Dv = Dv;
    p->edge_force = Fc + B * Dv; /* friction just outside the band */
    p->mode = HOLD;
    p->direction = 0;
    p->stack.data = NULL;
    p->stack.cap = 0;
    rc = err_finish(&err, start(p, 0.0, x0, v0, 0, &err));
    if (rc != DFWB_OK) {
        dfwb_friction_free(p);
        return rc;
    }
    *out = p;
    return DFWB_OK;
}

int dfwb_friction_set_input(dfwb_friction *p, double f, char *errbuf, size_t errlen)
{
    dfwb_err err;
    int rc;
    err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_set_input: NULL instance");
    rc = check(&err, "f", f, 1, "the input f must be a finite number (N)");
    if (rc != DFWB_OK)
        return rc;
    if (f != p->drive.f) {
        close_piece(p, p->t, &err);
        dfwb_drive_init(&p->drive, f, p->drive.F, p->drive.omega, p->drive.phi);
        rc = restart(p, p->t, &err);
    }
    return err_finish(&err, rc);
}

int dfwb_friction_advance(dfwb_friction *p, double t_end, char *errbuf, size_t errlen)
{
    dfwb_err err;
    double theta, limit, fired = 0.0;
    char rt[DFWB_REPR_SIZE], allowed[96];
    int rc;
    err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_advance: NULL instance");
    if (!(isfinite(t_end) && t_end >= p->t)) { /* the message is written only when refused */
        dfwb_repr(p->t, rt);
        strcpy(allowed, "the end of a step must be >= the current time ");
        strcat(allowed, rt);
        return check(&err, "t_end", t_end, 0, allowed);
    }
    /* bounds the search chunks (and every phase on the way) */
    rc = dfwb_drive_phase(&p->drive, t_end, "t_end", &theta, &err);
    if (rc != DFWB_OK)
        return rc;
    limit = DFWB_EVENTS_PER_PERIOD_LIMIT * (1.0 + (t_end - p->t) / p->period);
    for (;;) {
        int has, kind;
        double t_event;
        rc = next_event(p, t_end, &has, &t_event, &kind, &err);
        if (rc != DFWB_OK || !has || err.overflow != NULL)
            break;
        fired += 1.0;
        if (fired > limit) {
            char rte[DFWB_REPR_SIZE];
            dfwb_repr(p->t, rt);
            dfwb_repr(t_event, rte);
            rc = dfwb_fail(&err, DFWB_E_LIMIT,
                           "more than %d events per period between t = %s and t = %s (last event: %s); the "
                           "motion chatters below the plant's resolution",
                           DFWB_EVENTS_PER_PERIOD_LIMIT, rt, rte, dfwb_event_name(kind));
            break;
        }
        rc = fire(p, t_event, kind, &err);
        if (rc != DFWB_OK || err.overflow != NULL) /* Python raised there: not counted */
            break;
        p->events += 1; /* every friction event changes the motion */
        dfwb_log_add(&p->log, t_event, kind);
    }
    if (rc == DFWB_OK && err.overflow == NULL)
        p->t = t_end;
    return err_finish(&err, rc);
}

void dfwb_friction_output(const dfwb_friction *p, double out[4])
{
    double x, v, acc;
    if (p == NULL || out == NULL)
        return;
    dfwb_motion_state(&p->output, p->t, &x, &v);
    acc = dfwb_motion_acceleration(&p->output, p->t, v);
    out[0] = x;
    out[1] = v;
    out[2] = dfwb_drive_u(&p->drive, p->t) - p->M * acc;
    out[3] = p->mode == SLIDE ? (double)p->direction : 0.0;
}

int dfwb_friction_integrals(const dfwb_friction *p, double *re, double *im, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_cx piece[DFWB_HARMONICS_MAX + 1];
    int k;
    err_init(&err, errbuf, errlen);
    if (p == NULL || re == NULL || im == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_integrals: NULL instance or array");
    piece_integrals(p, p->t, piece, &err);
    for (k = 0; k <= p->harmonics; k++) {
        const dfwb_cx z = dfwb_cx_add(p->integrals[k], piece[k]);
        re[k] = z.re;
        im[k] = z.im;
    }
    return err_finish(&err, DFWB_OK);
}

double dfwb_friction_time(const dfwb_friction *p) { return p == NULL ? NAN : p->t; }

long long dfwb_friction_events(const dfwb_friction *p) { return p == NULL ? -1 : p->events; }

int dfwb_friction_harmonics(const dfwb_friction *p) { return p == NULL ? -1 : p->harmonics; }

double dfwb_friction_period(const dfwb_friction *p) { return p == NULL ? NAN : p->period; }

void dfwb_friction_drive(const dfwb_friction *p, double out[4])
{
    if (p != NULL && out != NULL)
        dfwb_drive_values(&p->drive, out);
}

dfwb_friction *dfwb_friction_copy(const dfwb_friction *p)
{
    dfwb_friction *q;
    if (p == NULL)
        return NULL;
    q = (dfwb_friction *)malloc(sizeof *q);
    if (q == NULL)
        return NULL;
    memcpy(q, p, sizeof *q);
    q->stack.data = NULL; /* a workspace of its own */
    q->stack.cap = 0;
    if (!dfwb_log_copy(&q->log, &p->log)) {
        free(q);
        return NULL;
    }
    return q;
}

void dfwb_friction_free(dfwb_friction *p)
{
    if (p == NULL)
        return;
    dfwb_stack_free(&p->stack);
    dfwb_log_free(&p->log);
    free(p);
}

void dfwb_friction_log(dfwb_friction *p, size_t capacity)
{
    if (p != NULL)
        dfwb_log_enable(&p->log, capacity);
}

size_t dfwb_friction_log_read(dfwb_friction *p, double *t, int *kind, size_t max)
{
    return p == NULL ? 0 : dfwb_log_read(&p->log, t, kind, max);
}

unsigned long long dfwb_friction_log_dropped(const dfwb_friction *p) { return p == NULL ? 0 : p->log.dropped; }

/* -- state as bytes ---------------------------------------------------------------------------- */
static void state_io(dfwb_io *io, dfwb_friction *p)
{
    int k;
    if (!io->reading) { /* canonical bytes: nothing stale */
        if (!p->nsearch)
            memset(&p->search, 0, sizeof p->search);
        if (!p->has_found) {
            p->found_t = 0.0;
            p->found_kind = 0;
        }
    }
    dfwb_io_f64(io, &p->M);
    dfwb_io_f64(io, &p->B);
    dfwb_io_f64(io, &p->Fc);
    dfwb_io_f64(io, &p->Fs);
    dfwb_io_f64(io, &p->Dv);
    dfwb_io_f64(io, &p->drive.f);
    dfwb_io_f64(io, &p->drive.F);
    dfwb_io_f64(io, &p->drive.omega);
    dfwb_io_f64(io, &p->drive.phi);
    dfwb_io_int(io, &p->harmonics);
    dfwb_io_f64(io, &p->t);
    dfwb_io_i64(io, &p->events);
    dfwb_io_int(io, &p->mode);
    dfwb_io_int(io, &p->direction);
    dfwb_io_f64(io, &p->t_piece);
    dfwb_io_motion(io, &p->output);
    dfwb_io_f64(io, &p->analytic);
    dfwb_io_int(io, &p->analytic_kind);
    dfwb_io_int(io, &p->nsearch);
    dfwb_io_f64(io, &p->search.sign);
    dfwb_io_f64(io, &p->search.offset);
    dfwb_io_int(io, &p->search.bounded);
    dfwb_io_f64(io, &p->search.K);
    dfwb_io_f64(io, &p->search.t_from);
    dfwb_io_int(io, &p->search.kind);
    dfwb_io_f64(io, &p->searched);
    dfwb_io_int(io, &p->has_found);
    dfwb_io_f64(io, &p->found_t);
    dfwb_io_int(io, &p->found_kind);
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++) {
        dfwb_io_f64(io, &p->integrals[k].re);
        dfwb_io_f64(io, &p->integrals[k].im);
    }
}

static size_t payload_size(void)
{
    dfwb_friction scratch;
    dfwb_io io;
    memset(&scratch, 0, sizeof scratch);
    dfwb_io_writer(&io, NULL);
    state_io(&io, &scratch);
    return io.pos;
}

int dfwb_friction_to_bytes(const dfwb_friction *p, unsigned char *buf, size_t buflen, size_t *size, char *errbuf,
                           size_t errlen)
{
    dfwb_err err;
    dfwb_friction copy;
    dfwb_io io;
    const size_t payload = payload_size(), needed = DFWB_STATE_HEADER + payload;
    int rc;
    err_init(&err, errbuf, errlen);
    if (size == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_to_bytes: NULL size");
    *size = needed;
    if (buf == NULL) /* a size query (p may be NULL) */
        return DFWB_OK;
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_to_bytes: NULL instance");
    rc = dfwb_state_buffer(needed, buflen, &err);
    if (rc != DFWB_OK)
        return rc;
    copy = *p; /* canonicalised while written: p stays as it is */
    dfwb_io_writer(&io, buf + DFWB_STATE_HEADER);
    state_io(&io, &copy);
    dfwb_state_header(buf, DFWB_PLANT_FRICTION, payload);
    return DFWB_OK;
}

static int validate(dfwb_friction *p, dfwb_err *err)
{
    const search_t *s = &p->search;
    int rc;
    p->stack.data = NULL;
    p->stack.cap = 0;
    memset(&p->log, 0, sizeof p->log);
    if ((rc = dfwb_state_check(err, "M", p->M, isfinite(p->M) && p->M > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "B", p->B, isfinite(p->B) && p->B >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "Fc", p->Fc, isfinite(p->Fc) && p->Fc >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "Fs", p->Fs, isfinite(p->Fs) && p->Fs >= p->Fc, "must be >= Fc")) != DFWB_OK
        || (rc = dfwb_state_check(err, "Dv", p->Dv, isfinite(p->Dv) && p->Dv >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_common(&p->drive, p->harmonics, p->t, p->events, err)) != DFWB_OK)
        return rc;
    p->period = DFWB_TWO_PI / p->drive.omega;
    p->edge_force = p->Fc + p->B * p->Dv;
    if ((rc = dfwb_state_check_integrals(p->integrals, p->harmonics, err)) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "mode", p->mode, p->mode == HOLD || p->mode == SLIDE || p->mode == PUSH,
                                      "must be 0 (hold), 1 (slide) or 2 (push)")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "direction", p->direction, -1 <= p->direction && p->direction <= 1,
                                      "must be -1, 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "has_found", p->has_found, p->has_found == 0 || p->has_found == 1,
                                      "must be 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check_piece(p->t, p->period, p->t_piece, p->searched, p->analytic, p->has_found,
                                        p->found_t, err)) != DFWB_OK
        || (rc = dfwb_state_motion(&p->output, "output", &p->drive, p->t, err)) != DFWB_OK
        || (rc = dfwb_state_check(err, "output motion's t0", p->output.t0, p->output.t0 == p->t_piece,
                                  "must be the piece's start t_piece")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "analytic_kind", p->analytic_kind, p->analytic_kind == KIND_NONE
                                      || p->analytic_kind == BREAK_UP || p->analytic_kind == BREAK_DOWN
                                      || p->analytic_kind == RELEASE, "must be none, break+, break- or release"))
               != DFWB_OK)
        return rc;
    if (!isinf(p->analytic) && p->analytic_kind == KIND_NONE)
        return dfwb_fail(err, DFWB_E_STATE, "the state's analytic event is out of range: a finite one has a kind");
    if (!(p->mode == HOLD ? p->nsearch == 0 && p->direction == 0
          : p->nsearch == 1 && p->direction != 0
                && s->kind == (p->mode == PUSH ? EDGE : BAND)
                && (p->mode == PUSH ? p->analytic_kind == RELEASE : p->analytic_kind == KIND_NONE)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's piece is out of range: its searches and events do not "
                         "match its mode");
    if (p->nsearch) {
        if (!((s->sign == 1.0 || s->sign == -1.0) && isfinite(s->offset) && (s->bounded == 0 || s->bounded == 1)
              && s->K >= 0.0 /* +inf allowed */ && s->t_from >= p->t_piece /* +inf allowed */))
            return dfwb_fail(err, DFWB_E_STATE, "the state's search is out of range: needs sign +-1, a finite "
                             "offset, K >= 0 and t_from >= t_piece");
        if (p->has_found && p->found_kind != s->kind)
            return dfwb_fail(err, DFWB_E_STATE, "the state's found event is out of range: its kind is not the "
                             "search's");
    } else {
        if (s->sign != 0.0 || s->offset != 0.0 || s->bounded != 0 || s->K != 0.0 || s->t_from != 0.0 || s->kind != 0)
            return dfwb_fail(err, DFWB_E_STATE, "the state's search is out of range: an unused search must be zeros");
        if (p->has_found)
            return dfwb_fail(err, DFWB_E_STATE, "the state's found event is out of range: there is no search");
    }
    if (!p->has_found && !(p->found_t == 0.0 && p->found_kind == 0))
        return dfwb_fail(err, DFWB_E_STATE, "the state's found event is out of range: must be 0 when none is found");
    return DFWB_OK;
}

int dfwb_friction_from_bytes(const unsigned char *buf, size_t len, dfwb_friction **out, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_friction *p;
    dfwb_io io;
    const size_t payload = payload_size();
    int rc;
    err_init(&err, errbuf, errlen);
    if (out == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_friction_from_bytes: NULL out");
    *out = NULL;
    rc = dfwb_state_open(buf, len, DFWB_PLANT_FRICTION, payload, &err);
    if (rc != DFWB_OK)
        return rc;
    p = (dfwb_friction *)calloc(1, sizeof *p);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_MEMORY, "out of memory (a dfwb_friction)");
    dfwb_io_reader(&io, buf + DFWB_STATE_HEADER, payload);
    state_io(&io, p);
    rc = io.bad_int ? dfwb_fail(&err, DFWB_E_STATE, "the state holds an integer field out of range") : validate(p, &err);
    if (rc != DFWB_OK) {
        dfwb_friction_free(p);
        return rc;
    }
    *out = p;
    return DFWB_OK;
}
