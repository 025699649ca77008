/* backlash.c - two masses with a clearance and impacts, integrated exactly: a port of fmus/backlash.py
 * (TwoMassBacklash) on the piece machinery of plant.c. The API is documented in dfwb_core.h.
 *
 * M2 carries the force u = f + F cos(omega t + phi); M1 is free; the gap g = x2 - x1 stays in [0, h].
 * The state is the centre of mass (one closed form the impacts never touch) and the relative motion
 * (g, w = g'), g'' = u / M2 between impacts, which are first zeros of the closed-form gap at 0 and h.
 * An impact is w -> -eps w; when u presses the masses together and the next bounce would rise less than
 * tol_h = 1e-12 h, they move together until u pulls them apart (an analytic crossing of zero). Leaving a
 * wall, the gap cannot return to it before the separation speed falls to zero: that apex is searched
 * first (an uncounted event).
 */
#include <math.h>
#include <stdio.h>
#include <stddef.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "loop.h"
#include "plant.h"

#define MIN_CLEARANCE 1e-290 /* m: the Zeno tolerance 1e-12 h stays a normal float */
#define MIN_CLEARANCE_TEXT "1e-290"

enum { FREE = 0, LOWER = 1, UPPER = 2 }; /* the contact output: free, at gap 0, at gap h */

typedef struct dfwb_backlash dfwb_backlash;

struct dfwb_backlash {
    dfwb_pw pw; /* first: the piece machinery (its output is x1) */
    double M1, M2, h, eps, total, r1, r2, tol_h;
    long long impacts;
    int contact, departing;
    dfwb_motion cm;  /* the centre of mass */
    dfwb_motion gap; /* the relative motion while free (the searches' subject) */
};

/* SIDE: sigma of a boundary, pressing into it means sigma u > 0 (FREE: 0) */
static int side_sigma(int side) { return side == LOWER ? -1 : (side == UPPER ? 1 : 0); }

static double wall_of(const dfwb_backlash *p, int side) { return side == LOWER ? 0.0 : p->h; }

/* -- state ---------------------------------------------------------------------------- */
static void centre(dfwb_backlash *p, double t, double x_cm, double v_cm)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion_init(&p->cm, t, x_cm, v_cm, 0.0, d->f / p->total, d->F / p->total, d->omega, d->phi);
}

/* (g, w) at t */
static void relative(const dfwb_backlash *p, double t, double *g, double *w)
{
    if (p->contact == FREE) {
        dfwb_motion_state(&p->gap, t, g, w);
        return;
    }
    *g = wall_of(p, p->contact);
    *w = 0.0;
}

/* -- pieces ------------------------------------------------------------------------------ */
/* x1's closed form from t: free (a = b = 0) or riding with the centre of mass. */
static void output_motion(const dfwb_backlash *p, dfwb_motion *m, double t, double g, double w, double a, double b)
{
    const dfwb_drive *d = &p->pw.drive;
    double x_cm, v_cm;
    dfwb_motion_state(&p->cm, t, &x_cm, &v_cm);
    dfwb_motion_init(m, t, x_cm - p->r2 * g, v_cm - p->r2 * w, 0.0, a, b, d->omega, d->phi);
}

static void boundary_searches(dfwb_backlash *p, double t, int skip)
{
    const double K = fabs(p->gap.a) + fabs(p->gap.b);
    if (skip != -1) /* g, w */
        dfwb_pw_add_search(&p->pw, DFWB_SEARCH_POSITION, 1.0, 0, 0.0, K, 0, t, DFWB_EVENT_WALL_LOWER);
    if (skip != 1) /* h - g, -w */
        dfwb_pw_add_search(&p->pw, DFWB_SEARCH_POSITION, 1.0, 1, p->h, K, 0, t, DFWB_EVENT_WALL_UPPER);
}

/* Flight; departing = sigma of the boundary just left (0: none). */
static int free_flight(dfwb_backlash *p, double t, double g, double w, int departing, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion out;
    p->contact = FREE;
    p->departing = departing;
    dfwb_motion_init(&p->gap, t, g, w, 0.0, d->f / p->M2, d->F / p->M2, d->omega, d->phi);
    output_motion(p, &out, t, g, w, 0.0, 0.0);
    dfwb_pw_begin(&p->pw, t, &out, INFINITY, 0);
    boundary_searches(p, t, departing);
    if (departing) {
        /* the gap cannot return to the boundary it left before the separation speed -sigma w falls to 0 */
        const double sep = -(double)departing * w;
        double t_from = t, K;
        if (!(sep > 0.0)) {
            const int rc = dfwb_drive_crossing(d, t, 0.0, departing > 0, &t_from, err);
            if (rc != DFWB_OK)
                return rc;
        }
        K = dfwb_motion_curvature_bound(&p->gap, 0, 0.0, err);
        dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, -(double)departing, 0, 0.0, K, 0, t_from,
                           DFWB_EVENT_APEX);
    }
    return DFWB_OK;
}

/* The masses move together until u stops pressing them into the boundary. */
static int contact(dfwb_backlash *p, double t, int side, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion out;
    double t_release;
    int rc;
    p->contact = side;
    p->departing = 0;
    output_motion(p, &out, t, wall_of(p, side), 0.0, d->f / p->total, d->F / p->total);
    rc = dfwb_drive_crossing(d, t, 0.0, side_sigma(side) < 0, &t_release, err);
    if (rc != DFWB_OK)
        return rc;
    dfwb_pw_begin(&p->pw, t, &out, t_release, DFWB_EVENT_RELEASE);
    return DFWB_OK;
}

/* Impact (if closing), then contact or a flight away from the boundary. */
static int at_boundary(dfwb_backlash *p, double t, int side, double w, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    const int sigma = side_sigma(side);
    double u;
    int pressing, pulling;
    if ((double)sigma * w > 0.0) {
        w = -p->eps * w;
        p->impacts += 1;
    }
    u = dfwb_drive_u(d, t);
    pressing = sigma > 0 ? dfwb_drive_above(d, t, 0.0) : dfwb_drive_below(d, t, 0.0);
    pulling = sigma > 0 ? dfwb_drive_below(d, t, 0.0) : dfwb_drive_above(d, t, 0.0);
    if ((w == 0.0 && !pulling) || (pressing && 0.5 * w * w * p->M2 <= p->tol_h * fabs(u)))
        return contact(p, t, side, err);
    return free_flight(p, t, wall_of(p, side), w, sigma, err);
}

static int start(dfwb_backlash *p, double t, double g, double w, dfwb_err *err)
{
    if (g <= 0.0)
        return at_boundary(p, t, LOWER, w, err);
    if (g >= p->h)
        return at_boundary(p, t, UPPER, w, err);
    return free_flight(p, t, g, w, 0, err);
}

/* -- events ---------------------------------------------------------------------------- */
static int fire(void *plant, double t, int kind, int *counted, dfwb_err *err)
{
    dfwb_backlash *p = (dfwb_backlash *)plant;
    double g, w;
    if (kind == DFWB_EVENT_APEX) {
        p->departing = 0;
        dfwb_pw_set_searches(&p->pw, t);
        boundary_searches(p, t, 0);
        *counted = 0;
        return DFWB_OK;
    }
    relative(p, t, &g, &w);
    dfwb_pw_close_piece(&p->pw, t, err);
    *counted = 1;
    if (kind == DFWB_EVENT_RELEASE) {
        const int side = p->contact;
        return free_flight(p, t, wall_of(p, side), 0.0, side_sigma(side), err);
    }
    return at_boundary(p, t, kind == DFWB_EVENT_WALL_LOWER ? LOWER : UPPER, w, err);
}

static int restart(void *plant, double t, dfwb_err *err)
{
    dfwb_backlash *p = (dfwb_backlash *)plant;
    double g, w, x_cm, v_cm;
    relative(p, t, &g, &w);
    dfwb_motion_state(&p->cm, t, &x_cm, &v_cm);
    centre(p, t, x_cm, v_cm); /* the new input changes the centre's closed form */
    if (p->contact != FREE)
        return at_boundary(p, t, p->contact, 0.0, err);
    if (p->departing && -(double)p->departing * w <= 0.0) /* still at the wall it was leaving: the force decides */
        return at_boundary(p, t, p->departing < 0 ? LOWER : UPPER, w, err);
    if (p->departing)
        return free_flight(p, t, g, w, p->departing, err);
    return start(p, t, g, w, err);
}

/* -- state as bytes ---------------------------------------------------------------------------- */
static void state_io(dfwb_io *io, void *plant)
{
    dfwb_backlash *p = (dfwb_backlash *)plant;
    dfwb_pw_io(io, &p->pw);
    dfwb_io_f64(io, &p->M1);
    dfwb_io_f64(io, &p->M2);
    dfwb_io_f64(io, &p->h);
    dfwb_io_f64(io, &p->eps);
    dfwb_io_i64(io, &p->impacts);
    dfwb_io_int(io, &p->contact);
    dfwb_io_int(io, &p->departing);
    dfwb_io_motion(io, &p->cm);
    dfwb_io_motion(io, &p->gap);
}

/* The plant's own checks of a state read into p (the common part is checked first). */
static int validate(void *plant, dfwb_err *err)
{
    dfwb_backlash *p = (dfwb_backlash *)plant;
    const dfwb_pw *pw = &p->pw;
    char rh[DFWB_REPR_SIZE], allowed[128];
    int rc, i;
    if ((rc = dfwb_state_check(err, "M1", p->M1, isfinite(p->M1) && p->M1 > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "M2", p->M2, isfinite(p->M2) && p->M2 > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "h", p->h, isfinite(p->h) && p->h >= MIN_CLEARANCE,
                                  "must be >= " MIN_CLEARANCE_TEXT)) != DFWB_OK
        || (rc = dfwb_state_check(err, "eps", p->eps, 0.0 <= p->eps && p->eps <= 1.0, "must be in [0, 1]"))
               != DFWB_OK
        || (rc = dfwb_state_check_int(err, "impacts", p->impacts, p->impacts >= 0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "contact", p->contact, p->contact == FREE || p->contact == LOWER
                                      || p->contact == UPPER, "must be 0, 1 or 2")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "departing", p->departing, -1 <= p->departing && p->departing <= 1,
                                      "must be -1, 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_motion(&p->cm, "centre", &pw->drive, pw->t, err)) != DFWB_OK
        || (rc = dfwb_state_motion(&p->gap, "gap", &pw->drive, pw->t, err)) != DFWB_OK)
        return rc;
    if (pw->output.lam != 0.0 || p->cm.lam != 0.0 || p->gap.lam != 0.0)
        return dfwb_fail(err, DFWB_E_STATE, "the state's motions are out of range: a backlash has no damping");
    if (p->contact != FREE && !(pw->nsearch == 0 && pw->analytic_kind == DFWB_EVENT_RELEASE && p->departing == 0))
        return dfwb_fail(err, DFWB_E_STATE, "the state's contact piece is out of range: it must wait for a "
                         "release alone");
    if (p->contact == FREE && !(pw->analytic_kind == 0 && isinf(pw->analytic)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's free piece is out of range: it has no analytic event");
    dfwb_repr(p->h, rh);
    strcpy(allowed, "a wall search of a known side (level h = ");
    strcat(allowed, rh);
    strcat(allowed, ")");
    for (i = 0; i < pw->nsearch; i++) {
        const dfwb_search *s = &pw->searches[i];
        const int ok = !s->bounded
                       && (s->kind == DFWB_EVENT_APEX
                               ? s->type == DFWB_SEARCH_VELOCITY && !s->has_level
                               : s->type == DFWB_SEARCH_POSITION && s->sign == 1.0
                                     && ((s->kind == DFWB_EVENT_WALL_LOWER && !s->has_level)
                                         || (s->kind == DFWB_EVENT_WALL_UPPER && s->has_level && s->level == p->h)));
        if (!ok)
            return dfwb_fail(err, DFWB_E_STATE, "the state's search %d (kind %d) is out of range: %s", i, s->kind,
                             allowed);
    }
    /* derived, as the constructor computes them */
    p->total = p->M1 + p->M2;
    p->r1 = p->M1 / p->total;
    p->r2 = p->M2 / p->total;
    p->tol_h = 1e-12 * p->h;
    return DFWB_OK;
}

/* The parameter checks, in the Python check's order: shared by the plant and its closed loop. */
static int check_parameters(dfwb_err *err, double M1, double M2, double h, double eps, double x1_0, double v1_0,
                            double v2_0, double gap0)
{
    char rh[DFWB_REPR_SIZE], allowed[128];
    int rc;
    if ((rc = dfwb_check(err, "M1", M1, M1 > 0.0, "M1 must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "M2", M2, M2 > 0.0, "M2 must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "h", h, h >= MIN_CLEARANCE, "h must be >= " MIN_CLEARANCE_TEXT " (m)")) != DFWB_OK
        || (rc = dfwb_check(err, "eps", eps, 0.0 <= eps && eps <= 1.0, "eps must be in [0, 1]")) != DFWB_OK)
        return rc;
    dfwb_repr(h, rh); /* h is valid here */
    strcpy(allowed, "gap0 must be in [0, h] = [0, ");
    strcat(allowed, rh);
    strcat(allowed, "] (m), or -1 in an FMU (h/2)");
    if ((rc = dfwb_check(err, "gap0", gap0, 0.0 <= gap0 && gap0 <= h, allowed)) != DFWB_OK
        || (rc = dfwb_check(err, "x1_0", x1_0, 1, "x1_0 must be a finite number")) != DFWB_OK
        || (rc = dfwb_check(err, "v1_0", v1_0, 1, "v1_0 must be a finite number")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "v2_0", v2_0, 1, "v2_0 must be a finite number");
}

/* -- the closed loop (BacklashLoop of fmus/backlash.py): q = (x1, v1, gap, w = v2 - v1), y = x1, f on M2 ---------- */
/* BacklashLoop.__init__: {M1, M2, h, eps, x1_0, v1_0, v2_0, gap0}; par = {M1, M2, h, eps, r2, tol_h} */
static int loop_check(dfwb_loop *L, const double *v, double *q0, dfwb_err *err)
{
    const double M1 = v[DFWB_BACKLASH_LOOP_M1], M2 = v[DFWB_BACKLASH_LOOP_M2], h = v[DFWB_BACKLASH_LOOP_h];
    const double eps = v[DFWB_BACKLASH_LOOP_eps], gap0 = v[DFWB_BACKLASH_LOOP_gap0];
    const double x1_0 = v[DFWB_BACKLASH_LOOP_x1_0], v1_0 = v[DFWB_BACKLASH_LOOP_v1_0];
    const double v2_0 = v[DFWB_BACKLASH_LOOP_v2_0];
    int rc;
    if ((rc = check_parameters(err, M1, M2, h, eps, x1_0, v1_0, v2_0, gap0)) != DFWB_OK)
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

/* BacklashLoop.check_coordinates */
static int loop_check_state(const dfwb_loop *L, const double *q, dfwb_err *err)
{
    const double h = L->par[2];
    char rh[DFWB_REPR_SIZE], allowed[96];
    dfwb_repr(h, rh);
    snprintf(allowed, sizeof allowed, "the gap must be in [0, h] = [0, %s] (m)", rh);
    return dfwb_check(err, "gap", q[2], 0.0 <= q[2] && q[2] <= h, allowed);
}

/* the sigma of a contact key: -1 held at gap 0, +1 at gap h */
static int contact_sigma(int key) { return key == DFWB_LOOP_CONTACT_LOWER ? -1 : 1; }

/* BacklashLoop.plant_mode */
static void loop_mode(const dfwb_loop *L, int key, dfwb_plant_mode *pm)
{
    const double M1 = L->par[0], M2 = L->par[1], h = L->par[2];
    pm->P[0][1] = 1.0;
    if (key == DFWB_LOOP_FREE) {
        pm->P[2][3] = 1.0;
        pm->phi[3] = 1.0 / M2;
        dfwb_loop_add_event(pm, DFWB_EVENT_WALL_LOWER, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0); /* g > 0 */
        dfwb_loop_add_event(pm, DFWB_EVENT_WALL_UPPER, 0.0, 0.0, -1.0, 0.0, 0.0, h); /* h - g > 0 */
        return;
    }
    pm->phi[1] = 1.0 / (M1 + M2);
    dfwb_loop_add_event(pm, DFWB_EVENT_RELEASE, 0.0, 0.0, 0.0, 0.0, (double)contact_sigma(key), 0.0); /* pressing */
}

/* BacklashLoop._at_wall: at a wall after any impact, contact or a flight away from it */
static int loop_at_wall(dfwb_loop *L, int sigma, double *X, int *key, int *departing, dfwb_err *err)
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
    f = dfwb_loop_feedback(L, X);
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

/* BacklashLoop.CONTACTS, wall and half_play (the drivetrain's too): M2 reaches the upper wall (drags M1 up) / the
 * lower; 1/2 */
int dfwb_loop_gap_contact(int kind)
{
    return kind == DFWB_EVENT_WALL_UPPER ? 1 : kind == DFWB_EVENT_WALL_LOWER ? -1 : 0;
}

int dfwb_loop_gap_wall(const dfwb_loop *L, const double *X)
{
    return 0.0 < X[2] && X[2] < L->par[2] ? 0 : X[2] <= 0.0 ? -1 : 1;
}

double dfwb_loop_gap_half_play(const dfwb_loop *L)
{
    (void)L;
    return 0.5;
}

static int loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    const int side = dfwb_loop_gap_wall(L, X);
    if (!side) {
        *key = DFWB_LOOP_FREE;
        return DFWB_OK;
    }
    return loop_at_wall(L, side, X, key, departing, err);
}

static int loop_fire(dfwb_loop *L, int kind, double *X, int *key, int *departing, dfwb_err *err)
{
    int sigma;
    double w;
    if (kind == DFWB_EVENT_RELEASE) {
        X[3] = 0.0;
        *departing = contact_sigma(L->hy.key) < 0 ? 0 : 1;
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
    return loop_at_wall(L, sigma, X, key, departing, err);
}

static const char *const LOOP_COORDINATES[] = {"x1", "v1", "gap", "w"};

static const dfwb_loop_class LOOP = {4, 0, DFWB_LOOP_BACKLASH_PARAMS, 6, "a two-mass backlash", LOOP_COORDINATES,
                                            "('x1', 'v1', 'gap', 'w')", loop_check, loop_check_state, loop_mode,
                                            loop_initial, loop_fire, 3, NULL, NULL, -1, NULL, 0, "BacklashLoop", dfwb_loop_gap_contact,
                                            dfwb_loop_gap_wall, dfwb_loop_gap_half_play};

/* -- the class ------------------------------------------------------------------------------------ */
/* TwoMassBacklash.__init__, then PiecewisePlant's: the order of the Python constructor (gap0 given: None is h/2) */
static int init(void *plant, const double *params, dfwb_err *err)
{
    dfwb_backlash *p = (dfwb_backlash *)plant;
    const double M1 = params[DFWB_BACKLASH_M1], M2 = params[DFWB_BACKLASH_M2], h = params[DFWB_BACKLASH_h];
    const double eps = params[DFWB_BACKLASH_eps], F = params[DFWB_BACKLASH_F];
    const double omega = params[DFWB_BACKLASH_omega], phi = params[DFWB_BACKLASH_phi];
    const double x1_0 = params[DFWB_BACKLASH_x1_0], v1_0 = params[DFWB_BACKLASH_v1_0];
    const double v2_0 = params[DFWB_BACKLASH_v2_0], gap0 = params[DFWB_BACKLASH_gap0], f = params[DFWB_BACKLASH_f];
    const double harmonics = params[DFWB_BACKLASH_harmonics];
    int rc;
    if ((rc = check_parameters(err, M1, M2, h, eps, x1_0, v1_0, v2_0, gap0)) != DFWB_OK
        || (rc = dfwb_check_drive(err, F, omega, phi, f, harmonics)) != DFWB_OK)
        return rc;
    dfwb_pw_init(&p->pw, F, omega, phi, f, harmonics);
    p->M1 = M1, p->M2 = M2, p->h = h, p->eps = eps;
    p->total = M1 + M2;
    p->r1 = M1 / p->total; /* x1 = x_cm - r2 g, x2 = x_cm + r1 g */
    p->r2 = M2 / p->total;
    p->tol_h = 1e-12 * h;
    p->impacts = 0;
    p->contact = FREE;
    p->departing = 0;
    centre(p, 0.0, x1_0 + p->r2 * gap0, p->r1 * v1_0 + p->r2 * v2_0);
    return dfwb_err_finish(err, start(p, 0.0, gap0, v2_0 - v1_0, err));
}

/* {x1, v1, x2, v2, gap} */
static void output(const void *plant, double *out)
{
    const dfwb_backlash *p = (const dfwb_backlash *)plant;
    double x1, v1, g, w, x_cm, v_cm;
    const double t = p->pw.t;
    dfwb_motion_state(&p->pw.output, t, &x1, &v1);
    relative(p, t, &g, &w);
    out[0] = x1;
    out[1] = v1;
    out[4] = g;
    if (p->contact != FREE) { /* riding together: one closed form for both */
        out[2] = x1 + g;
        out[3] = v1;
        return;
    }
    dfwb_motion_state(&p->cm, t, &x_cm, &v_cm);
    out[2] = x_cm + p->r1 * g;
    out[3] = v_cm + p->r1 * w;
}

/* 0 contact (0 free, 1 at gap 0, 2 at gap h), 1 impacts */
static long long counter(const void *plant, size_t i)
{
    const dfwb_backlash *p = (const dfwb_backlash *)plant;
    return i == 0 ? (long long)p->contact : p->impacts;
}

static int same(const void *one, const void *other)
{
    const dfwb_backlash *a = (const dfwb_backlash *)one, *b = (const dfwb_backlash *)other;
    return dfwb_same_double(a->M1, b->M1) && dfwb_same_double(a->M2, b->M2) && dfwb_same_double(a->h, b->h)
           && dfwb_same_double(a->eps, b->eps) && dfwb_same_double(a->total, b->total)
           && dfwb_same_double(a->r1, b->r1) && dfwb_same_double(a->r2, b->r2)
           && dfwb_same_double(a->tol_h, b->tol_h);
}

static const dfwb_backlash zero_state = {0}; /* the state's size is counted on it */

const dfwb_plant_class dfwb_backlash_class = {
    DFWB_PLANT_BACKLASH, sizeof(dfwb_backlash), &zero_state, offsetof(dfwb_backlash, gap), fire, restart,
    state_io, validate, DFWB_BACKLASH_PARAMS, 5, 2, init, output, counter, same, &LOOP, NULL, NULL, NULL, NULL};
