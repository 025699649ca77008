/* friction.c - the friction mass, integrated exactly: a port of fmus/friction.py (FrictionMass) on the piece
 * machinery of plant.c (fmus/piecewise.py). The API is documented in dfwb_core.h.
 *
 * A piece holds the closed-form motion of the mass and its next event: an analytic instant (the force
 * crossing a level: break-away, release) or the first zero of the velocity's distance to the band (a
 * velocity search with an offset on the piece's own motion).
 *
 * Modes: hold (v constant, |v| <= Dv), push +-1 (inside the band, |u| > Fs), slide +-1.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "friction.h"
#include "loop.h"
#include "plant.h"

enum { HOLD = DFWB_FRICTION_HOLD, SLIDE = DFWB_FRICTION_SLIDE, PUSH = DFWB_FRICTION_PUSH };

/* EventKind (fmus/contract.py, DFWB_EVENT_*); NONE: a piece without an analytic event */
enum {
    KIND_NONE = 0,
    BREAK_UP = DFWB_EVENT_BREAK_UP,
    BREAK_DOWN = DFWB_EVENT_BREAK_DOWN,
    RELEASE = DFWB_EVENT_RELEASE,
    EDGE = DFWB_EVENT_EDGE,
    BAND = DFWB_EVENT_BAND
};


/* -- pieces ------------------------------------------------------------------------------- */
/* _motion: the mass under a constant force plus the drive's harmonic part, damped by lam */
static void mass_motion(const dfwb_friction *p, dfwb_motion *m, double t, double x, double v, double lam,
                        double force)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion_init(m, t, x, v, lam, force / p->M, d->F / p->M, d->omega, d->phi);
}

/* Velocity held inside the band (stick when Dv = 0) while |u| is small. */
static int hold(dfwb_friction *p, double t, double x, double v, dfwb_err *err)
{
    dfwb_motion motion;
    double up, down, t_up, t_down;
    int rc;
    p->mode = HOLD;
    p->direction = 0;
    up = v >= p->Dv ? (p->edge_force > p->Fs ? p->edge_force : p->Fs) : p->Fs;
    down = v <= -p->Dv ? (p->edge_force > p->Fs ? p->edge_force : p->Fs) : p->Fs;
    rc = dfwb_drive_crossing(&p->pw.drive, t, up, 1, &t_up, err);
    if (rc != DFWB_OK)
        return rc;
    rc = dfwb_drive_crossing(&p->pw.drive, t, -down, 0, &t_down, err);
    if (rc != DFWB_OK)
        return rc;
    dfwb_motion_init(&motion, t, x, v, 0.0, 0.0, 0.0, p->pw.drive.omega, p->pw.drive.phi);
    if (t_up <= t_down)
        dfwb_pw_begin(&p->pw, t, &motion, t_up, BREAK_UP);
    else
        dfwb_pw_begin(&p->pw, t, &motion, t_down, BREAK_DOWN);
    return DFWB_OK;
}

/* Inside the band with |u| > Fs: friction Fs opposes u, v moves towards s * Dv. */
static int push(dfwb_friction *p, double t, double x, double v, int s, dfwb_err *err)
{
    dfwb_motion motion;
    double t_release, K;
    int rc;
    p->mode = PUSH;
    p->direction = s;
    mass_motion(p, &motion, t, x, v, 0.0, p->pw.drive.f - (double)s * p->Fs);
    rc = dfwb_drive_crossing(&p->pw.drive, t, (double)s * p->Fs, s < 0, &t_release, err);
    if (rc != DFWB_OK)
        return rc;
    K = dfwb_motion_curvature_bound(&motion, 0, 0.0, err);
    dfwb_pw_begin(&p->pw, t, &motion, t_release, RELEASE);
    /* the gap to the edge: Dv - s v, -s v' */
    dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, (double)(-s), 1, p->Dv, K, 0, t, EDGE);
    return DFWB_OK;
}

/* Sliding in direction s until the velocity falls back to the band: the friction mass's closed form, or the
 * slide of a plant built on it (p->slide: the Stribeck mass's integrated one). */
static int exact_slide(dfwb_friction *p, double t, double x, double v, int s, int departing, dfwb_err *err);

static int slide(dfwb_friction *p, double t, double x, double v, int s, int departing, dfwb_err *err)
{
    if (p->slide != NULL) {
        p->mode = SLIDE;
        p->direction = s;
        return p->slide(p, t, x, v, s, departing, err);
    }
    return exact_slide(p, t, x, v, s, departing, err);
}

static int exact_slide(dfwb_friction *p, double t, double x, double v, int s, int departing, dfwb_err *err)
{
    dfwb_motion motion;
    double t_from = t, K;
    int rc, bounded;
    p->mode = SLIDE;
    p->direction = s;
    mass_motion(p, &motion, t, x, v, p->B / p->M, p->pw.drive.f - (double)s * p->Fc);
    if (departing) { /* leaving the band edge, s*v - Dv > 0 is proven while s*u > Fc + B Dv */
        rc = dfwb_drive_crossing(&p->pw.drive, t, (double)s * p->edge_force, s < 0, &t_from, err);
        if (rc != DFWB_OK)
            return rc;
    }
    /* with damping, K is a function of t (CurvatureBound): the initial velocity's part of v'' decays */
    bounded = p->B != 0.0;
    K = bounded ? 0.0 : dfwb_motion_curvature_bound(&motion, 0, 0.0, err);
    dfwb_pw_begin(&p->pw, t, &motion, INFINITY, KIND_NONE);
    /* the speed above the band: s v - Dv, s v' */
    dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, (double)s, 1, -p->Dv, K, bounded, t_from, BAND);
    return DFWB_OK;
}

/* Choose the mode from the state and the force at t; at_edge = s when v has just reached the band
 * edge s * Dv (up to rounding). The state stays continuous across the switch. */
int dfwb_friction_start(dfwb_friction *p, double t, double x, double v, int at_edge, dfwb_err *err)
{
    const double Dv = p->Dv;
    const dfwb_drive *d = &p->pw.drive;
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

/* -- events ---------------------------------------------------------------------------- */
int dfwb_friction_fire(void *plant, double t, int kind, int *counted, dfwb_err *err)
{
    dfwb_friction *p = (dfwb_friction *)plant;
    double x, v;
    int s = p->direction, rc;
    dfwb_pw_close_piece(&p->pw, t, err);
    if ((rc = dfwb_pw_state(&p->pw, t, &x, &v, err)) != DFWB_OK)
        return rc;
    *counted = 1; /* every friction event changes the motion */
    switch (kind) {
    case BREAK_UP:
    case BREAK_DOWN:
        s = kind == BREAK_UP ? 1 : -1;
        if ((double)s * v >= p->Dv)
            return slide(p, t, x, (double)s * p->Dv, s, 1, err);
        return push(p, t, x, v, s, err);
    case RELEASE: /* |u| falls to Fs: hold, or (Fs = 0) a push the other way */
        return dfwb_friction_start(p, t, x, v, 0, err);
    case EDGE: { /* pushed through the band to its edge s * Dv (Dv > 0) */
        const double edge = (double)s * p->edge_force;
        if (s > 0 ? dfwb_drive_above(&p->pw.drive, t, edge) : dfwb_drive_below(&p->pw.drive, t, edge))
            return slide(p, t, x, (double)s * p->Dv, s, 1, err);
        return hold(p, t, x, (double)s * p->Dv, err);
    }
    default: /* BAND: the sliding velocity reached the band edge */
        return dfwb_friction_start(p, t, x, v, s, err);
    }
}

int dfwb_friction_restart(void *plant, double t, dfwb_err *err)
{
    dfwb_friction *p = (dfwb_friction *)plant;
    double x, v;
    int at_edge, rc;
    if ((rc = dfwb_pw_state(&p->pw, t, &x, &v, err)) != DFWB_OK)
        return rc;
    at_edge = p->mode == SLIDE && fabs(v) <= p->Dv ? p->direction : 0;
    return dfwb_friction_start(p, t, x, v, at_edge, err);
}

/* -- state as bytes ---------------------------------------------------------------------------- */
void dfwb_friction_io(dfwb_io *io, void *plant)
{
    dfwb_friction *p = (dfwb_friction *)plant;
    dfwb_pw_io(io, &p->pw);
    dfwb_io_f64(io, &p->M);
    dfwb_io_f64(io, &p->B);
    dfwb_io_f64(io, &p->Fc);
    dfwb_io_f64(io, &p->Fs);
    dfwb_io_f64(io, &p->Dv);
    dfwb_io_int(io, &p->mode);
    dfwb_io_int(io, &p->direction);
}

/* The plant's own checks of a state read into p (the common part is checked first). */
static int validate(void *plant, dfwb_err *err)
{
    dfwb_friction *p = (dfwb_friction *)plant;
    const dfwb_pw *pw = &p->pw;
    const dfwb_search *s = &pw->searches[0];
    int rc;
    if ((rc = dfwb_friction_state_forces(p, err)) != DFWB_OK
        || (rc = dfwb_state_check(err, "Dv", p->Dv, isfinite(p->Dv) && p->Dv >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "mode", p->mode, p->mode == HOLD || p->mode == SLIDE || p->mode == PUSH,
                                      "must be 0 (hold), 1 (slide) or 2 (push)")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "direction", p->direction, -1 <= p->direction && p->direction <= 1,
                                      "must be -1, 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "analytic_kind", pw->analytic_kind, pw->analytic_kind == KIND_NONE
                                      || pw->analytic_kind == BREAK_UP || pw->analytic_kind == BREAK_DOWN
                                      || pw->analytic_kind == RELEASE, "must be none, break+, break- or release"))
               != DFWB_OK)
        return rc;
    if (!(p->mode == HOLD ? pw->nsearch == 0 && p->direction == 0
          : pw->nsearch == 1 && p->direction != 0
                && s->kind == (p->mode == PUSH ? EDGE : BAND)
                && (p->mode == PUSH ? pw->analytic_kind == RELEASE : pw->analytic_kind == KIND_NONE)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's piece is out of range: its searches and events do not "
                         "match its mode");
    /* push: Dv - s v (K a number); slide: s v - Dv (bounded when damped) */
    if (pw->nsearch == 1
        && !(s->type == DFWB_SEARCH_VELOCITY && s->has_level
             && s->sign == (double)(p->mode == PUSH ? -p->direction : p->direction)
             && s->level == (p->mode == PUSH ? p->Dv : -p->Dv)
             && s->bounded == (p->mode == SLIDE && p->B != 0.0)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's search 0 (kind %d) is out of range: not the velocity "
                         "search of its mode", s->kind);
    p->edge_force = p->Fc + p->B * p->Dv; /* derived, as the constructor computes it */
    return DFWB_OK;
}

int dfwb_friction_check_forces(dfwb_err *err, double M, double B, double Fc, double Fs)
{
    char rFc[DFWB_REPR_SIZE], allowed[96];
    int rc;
    strcpy(allowed, "Fs must be >= Fc = ");
    if (!(isfinite(Fs) && Fs >= Fc)) { /* the message is written only when refused */
        dfwb_repr(Fc, rFc);
        strcat(allowed, rFc);
        strcat(allowed, " (N)");
    }
    if ((rc = dfwb_check(err, "M", M, M > 0.0, "M must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "B", B, B >= 0.0, "B must be >= 0 (N.s/m)")) != DFWB_OK
        || (rc = dfwb_check(err, "Fc", Fc, Fc >= 0.0, "Fc must be >= 0 (N)")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "Fs", Fs, Fs >= Fc, allowed);
}

int dfwb_friction_state_forces(const dfwb_friction *p, dfwb_err *err)
{
    int rc;
    if ((rc = dfwb_state_check(err, "M", p->M, isfinite(p->M) && p->M > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "B", p->B, isfinite(p->B) && p->B >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "Fc", p->Fc, isfinite(p->Fc) && p->Fc >= 0.0, "must be >= 0")) != DFWB_OK)
        return rc;
    return dfwb_state_check(err, "Fs", p->Fs, isfinite(p->Fs) && p->Fs >= p->Fc, "must be >= Fc");
}

/* The parameter checks, in the Python check's order: shared by the plant and its closed loop. */
static int check_parameters(dfwb_err *err, double M, double B, double Fc, double Fs, double Dv, double x0, double v0,
                            int exact_stick)
{
    int rc = dfwb_friction_check_forces(err, M, B, Fc, Fs);
    if (rc != DFWB_OK)
        return rc;
    rc = exact_stick ? dfwb_check(err, "Dv", Dv, Dv == 0.0,
                                  "Dv must be 0 in the exact closed loop (the CVS model: exact stick)")
                     : dfwb_check(err, "Dv", Dv, Dv >= 0.0, "Dv must be >= 0 (m/s)");
    if (rc != DFWB_OK || (rc = dfwb_check(err, "x0", x0, 1, "x0 must be a finite number (m)")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "v0", v0, 1, "v0 must be a finite number (m/s)");
}

/* -- the closed loop (FrictionLoop of fmus/friction.py): q = (x, v), y = x ------------------------------------ */
/* FrictionLoop.__init__: {M, B, Fc, Fs, Dv, x0, v0} (exact stick: Dv = 0); par = {M, B, Fc, Fs} */
static int loop_check(dfwb_loop *L, const double *v, double *q0, dfwb_err *err)
{
    const double M = v[DFWB_FRICTION_LOOP_M], B = v[DFWB_FRICTION_LOOP_B], Fc = v[DFWB_FRICTION_LOOP_Fc];
    const double Fs = v[DFWB_FRICTION_LOOP_Fs], x0 = v[DFWB_FRICTION_LOOP_x0], v0 = v[DFWB_FRICTION_LOOP_v0];
    int rc;
    if ((rc = check_parameters(err, M, B, Fc, Fs, v[DFWB_FRICTION_LOOP_Dv], x0, v0, 1)) != DFWB_OK)
        return rc;
    L->par[0] = M;
    L->par[1] = B;
    L->par[2] = Fc;
    L->par[3] = Fs;
    q0[0] = x0;
    q0[1] = v0;
    return DFWB_OK;
}

/* FrictionLoop.plant_mode */
void dfwb_friction_loop_mode(const dfwb_loop *L, int key, dfwb_plant_mode *pm)
{
    const double M = L->par[0], B = L->par[1], Fc = L->par[2], Fs = L->par[3];
    const int s = key == DFWB_LOOP_SLIDE_UP ? 1 : -1;
    if (key == DFWB_LOOP_STICK) {
        dfwb_loop_add_event(pm, DFWB_EVENT_BREAK_UP, 0.0, 0.0, 0.0, 0.0, -1.0, Fs); /* Fs - f > 0 */
        dfwb_loop_add_event(pm, DFWB_EVENT_BREAK_DOWN, 0.0, 0.0, 0.0, 0.0, 1.0, Fs); /* f + Fs > 0 */
        return;
    }
    pm->P[0][1] = 1.0;
    pm->P[1][1] = -B / M;
    pm->p[1] = (double)(-s) * Fc / M;
    pm->phi[1] = 1.0 / M;
    dfwb_loop_add_event(pm, DFWB_EVENT_BAND, 0.0, (double)s, 0.0, 0.0, 0.0, 0.0); /* s v > 0 */
}

/* FrictionLoop._rest: at v = 0, stick while -Fs <= f <= Fs, else slide in the direction of f */
static int loop_rest(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
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

int dfwb_friction_loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    const double v = X[1];
    if (v != 0.0) {
        *key = v > 0.0 ? DFWB_LOOP_SLIDE_UP : DFWB_LOOP_SLIDE_DOWN;
        return DFWB_OK;
    }
    return loop_rest(L, X, key, departing, err);
}

int dfwb_friction_loop_fire(dfwb_loop *L, int kind, double *X, int *key, int *departing, dfwb_err *err)
{
    if (kind == DFWB_EVENT_BAND) {
        X[1] = 0.0;
        return loop_rest(L, X, key, departing, err);
    }
    *key = kind == DFWB_EVENT_BREAK_UP ? DFWB_LOOP_SLIDE_UP : DFWB_LOOP_SLIDE_DOWN;
    *departing = 0;
    return DFWB_OK;
}

/* FrictionLoop.slip: the sliding direction of mode key (0 stuck) */
int dfwb_friction_loop_slip(int key)
{
    return key == DFWB_LOOP_SLIDE_UP ? 1 : key == DFWB_LOOP_SLIDE_DOWN ? -1 : 0;
}

static const char *const LOOP_COORDINATES[] = {"x", "v"};

static const dfwb_loop_class LOOP = {2, 0, DFWB_LOOP_FRICTION_PARAMS, 4, "a friction mass", LOOP_COORDINATES,
                                            "('x', 'v')", loop_check, NULL, dfwb_friction_loop_mode, dfwb_friction_loop_initial,
                                            dfwb_friction_loop_fire, 3, NULL, NULL, -1, dfwb_friction_loop_slip,
                                            DFWB_EVENT_BAND, "FrictionLoop", NULL, NULL, NULL};

/* -- the class ------------------------------------------------------------------------------------ */
/* FrictionMass.__init__, then PiecewisePlant's: the order of the Python constructor */
static int init(void *plant, const double *params, dfwb_err *err)
{
    dfwb_friction *p = (dfwb_friction *)plant;
    const double M = params[DFWB_FRICTION_M], B = params[DFWB_FRICTION_B], Fc = params[DFWB_FRICTION_Fc];
    const double Fs = params[DFWB_FRICTION_Fs], Dv = params[DFWB_FRICTION_Dv], F = params[DFWB_FRICTION_F];
    const double omega = params[DFWB_FRICTION_omega], phi = params[DFWB_FRICTION_phi];
    const double x0 = params[DFWB_FRICTION_x0], v0 = params[DFWB_FRICTION_v0], f = params[DFWB_FRICTION_f];
    const double harmonics = params[DFWB_FRICTION_harmonics];
    int rc;
    if ((rc = check_parameters(err, M, B, Fc, Fs, Dv, x0, v0, 0)) != DFWB_OK
        || (rc = dfwb_check_drive(err, F, omega, phi, f, harmonics)) != DFWB_OK)
        return rc;
    dfwb_pw_init(&p->pw, F, omega, phi, f, harmonics);
    p->M = M, p->B = B, p->Fc = Fc, p->Fs = Fs, p->Dv = Dv;
    p->slide = NULL;
    p->edge_force = Fc + B * Dv; /* friction just outside the band */
    p->mode = HOLD;
    p->direction = 0;
    return dfwb_err_finish(err, dfwb_friction_start(p, 0.0, x0, v0, 0, err));
}

/* {x, v, Ff, mode} */
void dfwb_friction_output(const void *plant, double *out)
{
    const dfwb_friction *p = (const dfwb_friction *)plant;
    double x, v, acc;
    dfwb_err err;
    dfwb_err_init(&err, NULL, 0);
    dfwb_pw_state(&p->pw, p->pw.t, &x, &v, &err); /* the current time is always in the piece */
    acc = dfwb_pw_acceleration(&p->pw, p->pw.t, v);
    out[0] = x;
    out[1] = v;
    out[2] = dfwb_drive_u(&p->pw.drive, p->pw.t) - p->M * acc;
    out[3] = p->mode == SLIDE ? (double)p->direction : 0.0;
}

static int same(const void *one, const void *other)
{
    const dfwb_friction *a = (const dfwb_friction *)one, *b = (const dfwb_friction *)other;
    return dfwb_same_double(a->M, b->M) && dfwb_same_double(a->B, b->B) && dfwb_same_double(a->Fc, b->Fc)
           && dfwb_same_double(a->Fs, b->Fs) && dfwb_same_double(a->Dv, b->Dv)
           && dfwb_same_double(a->edge_force, b->edge_force);
}

static const dfwb_friction zero_state = {0}; /* the state's size is counted on it */

const dfwb_plant_class dfwb_friction_class = {
    DFWB_PLANT_FRICTION, sizeof(dfwb_friction), &zero_state, offsetof(dfwb_friction, pw.output), dfwb_friction_fire,
    dfwb_friction_restart, dfwb_friction_io, validate, DFWB_FRICTION_PARAMS, 4, 0, init, dfwb_friction_output, NULL, same,
    &LOOP, NULL, NULL, NULL, NULL};
