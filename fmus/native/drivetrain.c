/* drivetrain.c - a gear with play driving a load that sticks, integrated exactly: a port of fmus/drivetrain.py
 * (Drivetrain, DrivetrainLoop) on the piece machinery of plant.c. The API is documented in dfwb_core.h.
 *
 * M2 (the motor side) carries u = f + F cos(omega t + phi); a clearance h separates it from the load M1
 * (gap g = x2 - x1 in [0, h]), impacts of restitution eps; the load has viscous B, Coulomb Fc and static Fs
 * friction, stuck exactly at v1 = 0. In flight the gap is the difference of two closed forms (rel: the gap
 * were the load to keep its velocity; dev: the load's deviation from it), searched by the plant's own search
 * functions; together at a wall the masses part where N = M1 u + M2 (Fc s + B v) stops pressing. h = 0 is
 * a rigid coupling: the friction mass of mass M1 + M2.
 */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "loop.h"
#include "plant.h"

#define MIN_CLEARANCE 1e-290 /* m: h = 0 (rigid) or at least this */
#define MIN_CLEARANCE_TEXT "1e-290"

enum { FREE = 0, LOWER = 1, UPPER = 2 }; /* the contact output: free, at gap 0, at gap h */
/* the plant's own searches: GAP level + sign (x_rel - x_dev), SEPARATION sign (v_rel - v_dev) (the apex),
 * PRESSING sign (M1 u + M2 B v + M2 Fc s) of the masses together (sign = sigma, s = the slip) */
enum { GAP = DFWB_SEARCH_PLANT, SEPARATION, PRESSING };

typedef struct dfwb_drivetrain dfwb_drivetrain;

struct dfwb_drivetrain {
    dfwb_pw pw; /* first: the piece machinery (its output, x1, is the subject of the stop searches) */
    double M1, M2, h, eps, B, Fc, Fs, total, r2, tol_h;
    int rigid;
    long long impacts;
    int contact, slip, departing;
    dfwb_motion rel, dev; /* in flight: the gap is rel - dev */
};

static int side_sigma(int side) { return side == LOWER ? -1 : 1; }

static double wall_of(const dfwb_drivetrain *p, int side) { return side == LOWER ? 0.0 : p->h; }

static int sign_of(double v) { return v > 0.0 ? 1 : (v < 0.0 ? -1 : 0); }

/* Drive.du */
static double drive_du(const dfwb_drive *d, double t) { return -d->F * d->omega * sin(d->omega * t + d->phi); }

/* (g, w) at t */
static void relative(const dfwb_drivetrain *p, double t, double *g, double *w)
{
    double xr, vr, xd, vd;
    if (p->contact == FREE) {
        dfwb_motion_state(&p->rel, t, &xr, &vr);
        dfwb_motion_state(&p->dev, t, &xd, &vd);
        *g = xr - xd;
        *w = vr - vd;
        return;
    }
    *g = wall_of(p, p->contact);
    *w = 0.0;
}

/* DifferenceSearch and ForceSearch of fmus/piecewise.py */
static void search(const void *plant, const dfwb_search *s, double t, double *g, double *dg)
{
    const dfwb_drivetrain *p = (const dfwb_drivetrain *)plant;
    double xa, va, xb, vb;
    if (s->type == PRESSING) {
        const dfwb_motion *m = &p->pw.output;
        const double cu = s->sign * p->M1, cv = s->sign * p->M2 * p->B;
        const double c0 = s->sign * p->M2 * p->Fc * (double)p->slip;
        const double v = dfwb_motion_velocity(m, t);
        *g = c0 + cu * dfwb_drive_u(&p->pw.drive, t) + cv * v;
        *dg = cu * drive_du(&p->pw.drive, t) + cv * dfwb_motion_acceleration(m, t, v);
        return;
    }
    dfwb_motion_state(&p->rel, t, &xa, &va);
    dfwb_motion_state(&p->dev, t, &xb, &vb);
    if (s->type == SEPARATION) {
        const double d = dfwb_motion_acceleration(&p->rel, t, va) - dfwb_motion_acceleration(&p->dev, t, vb);
        *g = s->level + s->sign * (va - vb);
        *dg = s->sign * d;
        return;
    }
    *g = s->level + s->sign * (xa - xb);
    *dg = s->sign * (va - vb);
}

/* The bounds of its searches when bounded (a damped load): the walls' DecayingBound |u| / M2 + |x1''| with
 * x1'' = (a - lam v1) exp(-lam tau); the apex's MotionBound |v2''| + |v1''(t)|; the pressing force's MotionBound
 * M1 F omega^2 + M2 B |v''(t)| */
static double search_bound(const void *plant, const dfwb_search *s, double t)
{
    const dfwb_drivetrain *p = (const dfwb_drivetrain *)plant;
    const dfwb_motion *load = &p->pw.output;
    const dfwb_drive *d = &p->pw.drive;
    dfwb_err ignored = {NULL, 0, 0, NULL}; /* an overflow there is found when the search is made */
    if (s->type == SEPARATION)
        return dfwb_motion_curvature_bound(&p->rel, 0, 0.0, &ignored)
               + 1.0 * dfwb_motion_curvature_bound(&p->dev, 1, t, &ignored);
    if (s->type == PRESSING)
        return p->M1 * d->F * d->omega * d->omega + p->M2 * p->B * dfwb_motion_curvature_bound(load, 1, t, &ignored);
    return fabs(p->rel.a) + fabs(p->rel.b) + fabs(load->a - load->lam * load->v0) * exp(-load->lam * (t - load->t0));
}

/* -- pieces ------------------------------------------------------------------------------ */
static int together(dfwb_drivetrain *p, double t, int side, double x1, double v, int s, int departing,
                    dfwb_err *err);
static int flight(dfwb_drivetrain *p, double t, double x1, double v1, double g, double w, int departing,
                  dfwb_err *err);

/* N = M1 u + M2 (Fc s + B v) */
static double pressing(const dfwb_drivetrain *p, double t, int s, double v)
{
    return p->M1 * dfwb_drive_u(&p->pw.drive, t) + p->M2 * (p->Fc * (double)s + p->B * v);
}

/* Stuck together until |u| rises through Fs or (h > 0) u stops pressing. */
static int stuck(dfwb_drivetrain *p, double t, int side, double x1, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    dfwb_motion m;
    double t1, t2;
    int k1, k2, rc;
    p->contact = side;
    p->slip = 0;
    p->departing = 0;
    if (p->rigid) {
        k1 = DFWB_EVENT_BREAK_UP;
        k2 = DFWB_EVENT_BREAK_DOWN;
        if ((rc = dfwb_drive_crossing(d, t, p->Fs, 1, &t1, err)) != DFWB_OK
            || (rc = dfwb_drive_crossing(d, t, -p->Fs, 0, &t2, err)) != DFWB_OK)
            return rc;
    } else {
        const int sigma = side_sigma(side);
        k1 = sigma > 0 ? DFWB_EVENT_BREAK_UP : DFWB_EVENT_BREAK_DOWN;
        k2 = DFWB_EVENT_RELEASE;
        if ((rc = dfwb_drive_crossing(d, t, (double)sigma * p->Fs, sigma > 0, &t1, err)) != DFWB_OK
            || (rc = dfwb_drive_crossing(d, t, 0.0, sigma < 0, &t2, err)) != DFWB_OK)
            return rc;
    }
    dfwb_motion_init(&m, t, x1, 0.0, 0.0, 0.0, 0.0, d->omega, d->phi);
    if (t2 < t1) /* min() keeps the first of equals */
        dfwb_pw_begin(&p->pw, t, &m, t2, k2);
    else
        dfwb_pw_begin(&p->pw, t, &m, t1, k1);
    return DFWB_OK;
}

/* Together at the wall, v = 0: M2 leaves if u pulls it off; they slide if |u| > Fs; else stuck. */
static int rest(dfwb_drivetrain *p, double t, int side, double x1, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    const double Fs = p->Fs;
    int s;
    if (p->rigid) {
        s = dfwb_drive_above(d, t, Fs) ? 1 : (dfwb_drive_below(d, t, -Fs) ? -1 : 0);
    } else {
        const int sigma = side_sigma(side);
        if (sigma > 0 ? dfwb_drive_below(d, t, 0.0) : dfwb_drive_above(d, t, 0.0))
            return flight(p, t, x1, 0.0, wall_of(p, side), 0.0, sigma, err);
        s = (sigma > 0 ? dfwb_drive_above(d, t, Fs) : dfwb_drive_below(d, t, -Fs)) ? sigma : 0;
    }
    if (s)
        return together(p, t, side, x1, 0.0, s, 1, err);
    return stuck(p, t, side, x1, err);
}

/* Impact (if closing), then the masses together or a flight away from the wall. */
static int at_boundary(dfwb_drivetrain *p, double t, int side, double x1, double v1, double w, dfwb_err *err)
{
    const int sigma = side_sigma(side);
    double v;
    if (p->rigid) { /* plastic at once: the common velocity */
        v1 = v1 + p->r2 * w;
        w = 0.0;
    } else if ((double)sigma * w > 0.0) { /* closing: Newton's impact law, momentum kept */
        const double next = -p->eps * w;
        v1 += p->r2 * (w - next);
        w = next;
        p->impacts += 1;
    }
    v = v1 + p->r2 * w;
    if (v == 0.0 && w == 0.0)
        return rest(p, t, side, x1, err);
    if (v != 0.0) {
        const int s = sign_of(v);
        const double N = pressing(p, t, s, v);
        if (p->rigid
            || ((double)sigma * N > 0.0 && (w == 0.0 || 0.5 * w * w * p->M1 * p->M2 <= p->tol_h * fabs(N))))
            return together(p, t, side, x1, v, s, 0, err);
    }
    return flight(p, t, x1, v1, wall_of(p, side), w, sigma, err);
}

static int start(dfwb_drivetrain *p, double t, double x1, double v1, double g, double w, dfwb_err *err)
{
    if (p->rigid || g <= 0.0)
        return at_boundary(p, t, LOWER, x1, v1, w, err);
    if (g >= p->h)
        return at_boundary(p, t, UPPER, x1, v1, w, err);
    return flight(p, t, x1, v1, g, w, 0, err);
}

/* Sliding together in direction s until v = 0 or (h > 0) they part; departing from v = 0. */
static int together(dfwb_drivetrain *p, double t, int side, double x1, double v, int s, int departing,
                    dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    const double M = p->total;
    dfwb_motion m;
    double t_from = t, K;
    int rc, bounded;
    p->contact = side;
    p->slip = s;
    p->departing = 0;
    dfwb_motion_init(&m, t, x1, v, p->B / M, (d->f - (double)s * p->Fc) / M, d->F / M, d->omega, d->phi);
    if (departing) { /* leaving v = 0, s v > 0 is proven while s u > Fc */
        rc = dfwb_drive_crossing(d, t, (double)s * p->Fc, s < 0, &t_from, err);
        if (rc != DFWB_OK)
            return rc;
    }
    bounded = m.lam != 0.0;
    K = bounded ? 0.0 : dfwb_motion_curvature_bound(&m, 0, 0.0, err);
    dfwb_pw_begin(&p->pw, t, &m, INFINITY, 0);
    dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, (double)s, 0, 0.0, K, bounded, t_from, DFWB_EVENT_BAND);
    if (!p->rigid) { /* |N''| <= M1 F omega^2 + M2 B |v''|, the latter decaying (bounded) */
        const double K_force = bounded ? 0.0 : p->M1 * d->F * d->omega * d->omega;
        dfwb_pw_add_search(&p->pw, PRESSING, (double)side_sigma(side), 0, 0.0, K_force, bounded, t,
                           DFWB_EVENT_RELEASE);
    }
    return DFWB_OK;
}

/* The walls (but the one just left) and the load's stop. */
static void flight_searches(dfwb_drivetrain *p, double t, int skip, dfwb_err *err)
{
    const dfwb_motion *load = &p->pw.output;
    /* |g''| <= |u| / M2 + |x1''|, and x1'' = (a - lam v1) exp(-lam tau) (the load's force has no sine) */
    const int decaying = load->lam != 0.0;
    const double K = decaying ? 0.0 : fabs(p->rel.a) + fabs(p->rel.b) + fabs(load->a - load->lam * load->v0);
    if (skip != -1) /* g */
        dfwb_pw_add_search(&p->pw, GAP, 1.0, 0, 0.0, K, decaying, t, DFWB_EVENT_WALL_LOWER);
    if (skip != 1) /* h - g */
        dfwb_pw_add_search(&p->pw, GAP, -1.0, 1, p->h, K, decaying, t, DFWB_EVENT_WALL_UPPER);
    if (p->slip) {
        const int bounded = load->lam != 0.0;
        const double K_stop = bounded ? 0.0 : dfwb_motion_curvature_bound(load, 0, 0.0, err);
        dfwb_pw_add_search(&p->pw, DFWB_SEARCH_VELOCITY, (double)p->slip, 0, 0.0, K_stop, bounded, t,
                           DFWB_EVENT_BAND);
    }
}

/* From when the separation speed -sigma w is proven positive (it is 0 when the masses part). */
static int apex_from(dfwb_drivetrain *p, double t, double w, double v1, int sigma, double *t_from, dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    const dfwb_motion *load = &p->pw.output;
    double accel, n0, n1, K;
    if (-(double)sigma * w > 0.0) {
        *t_from = t;
        return DFWB_OK;
    }
    if (!p->slip) /* w' = u / M2: positive until u presses again */
        return dfwb_drive_crossing(d, t, 0.0, sigma > 0, t_from, err);
    accel = load->a - load->lam * v1;
    n0 = -(double)sigma * pressing(p, t, p->slip, v1);
    if (!(n0 > 0.0)) /* max(n0, 0.0) */
        n0 = 0.0;
    n1 = -(double)sigma * (p->M1 * drive_du(d, t) + p->M2 * p->B * accel);
    K = p->M1 * d->F * d->omega * d->omega + p->M2 * p->B * load->lam * fabs(accel);
    if (!(n0 > 0.0 || n1 > 0.0))
        *t_from = t; /* tangent: an immediate apex, then the wall decides */
    else if (K == 0.0)
        *t_from = n1 >= 0.0 ? INFINITY : t + 0.5 * n0 / -n1;
    else
        *t_from = t + 0.5 * (n1 + sqrt(n1 * n1 + 2.0 * K * n0)) / K;
    return DFWB_OK;
}

/* M2 free, the load sliding or stuck; departing = sigma of the wall just left (0: none). */
static int flight(dfwb_drivetrain *p, double t, double x1, double v1, double g, double w, int departing,
                  dfwb_err *err)
{
    const dfwb_drive *d = &p->pw.drive;
    const int s = sign_of(v1);
    const double lam = s ? p->B / p->M1 : 0.0, a = s ? -(double)s * p->Fc / p->M1 : 0.0;
    dfwb_motion load;
    p->contact = FREE;
    p->slip = s;
    p->departing = departing;
    dfwb_motion_init(&p->rel, t, g, w, 0.0, d->f / p->M2, d->F / p->M2, d->omega, d->phi);
    dfwb_motion_init(&p->dev, t, 0.0, 0.0, lam, a - lam * v1, 0.0, d->omega, d->phi);
    dfwb_motion_init(&load, t, x1, v1, lam, a, 0.0, d->omega, d->phi);
    dfwb_pw_begin(&p->pw, t, &load, INFINITY, 0);
    flight_searches(p, t, departing, err);
    if (departing) { /* |w''| <= |v2''| + |v1''|, the latter decaying (bounded) */
        const int bounded = p->dev.lam != 0.0;
        const double K = bounded ? 0.0 : dfwb_motion_curvature_bound(&p->rel, 0, 0.0, err);
        double t_from;
        const int rc = apex_from(p, t, w, v1, departing, &t_from, err);
        if (rc != DFWB_OK)
            return rc;
        dfwb_pw_add_search(&p->pw, SEPARATION, -(double)departing, 0, 0.0, K, bounded, t_from, DFWB_EVENT_APEX);
    }
    return DFWB_OK;
}

/* -- events ---------------------------------------------------------------------------- */
static int fire(void *plant, double t, int kind, int *counted, dfwb_err *err)
{
    dfwb_drivetrain *p = (dfwb_drivetrain *)plant;
    double x1, v1, g, w;
    const int side = p->contact;
    if (kind == DFWB_EVENT_APEX) {
        p->departing = 0;
        dfwb_pw_set_searches(&p->pw, t);
        flight_searches(p, t, 0, err);
        *counted = 0;
        return DFWB_OK;
    }
    dfwb_motion_state(&p->pw.output, t, &x1, &v1);
    relative(p, t, &g, &w);
    dfwb_pw_close_piece(&p->pw, t, err);
    *counted = 1;
    if (side == FREE) {
        if (kind == DFWB_EVENT_BAND) /* the load stops, and sticks: nothing pushes it */
            return flight(p, t, x1, 0.0, g, w, p->departing, err);
        return at_boundary(p, t, kind == DFWB_EVENT_WALL_LOWER ? LOWER : UPPER, x1, v1, w, err);
    }
    if (kind == DFWB_EVENT_BAND)
        return rest(p, t, side, x1, err);
    if (kind == DFWB_EVENT_RELEASE)
        return flight(p, t, x1, p->slip ? v1 : 0.0, wall_of(p, side), 0.0, side_sigma(side), err);
    return together(p, t, side, x1, 0.0, kind == DFWB_EVENT_BREAK_UP ? 1 : -1, 1, err);
}

static int restart(void *plant, double t, dfwb_err *err)
{
    dfwb_drivetrain *p = (dfwb_drivetrain *)plant;
    double x1, v1, g, w;
    const int side = p->contact, departing = p->departing;
    dfwb_motion_state(&p->pw.output, t, &x1, &v1);
    relative(p, t, &g, &w);
    if (side == FREE) {
        if (departing && -(double)departing * w <= 0.0) /* still at the wall it was leaving: the force decides */
            return at_boundary(p, t, departing < 0 ? LOWER : UPPER, x1, v1, w, err);
        return flight(p, t, x1, v1, g, w, departing, err);
    }
    if (p->slip)
        return at_boundary(p, t, side, x1, v1, 0.0, err); /* together while the new force presses */
    return rest(p, t, side, x1, err);
}

/* -- state as bytes ---------------------------------------------------------------------------- */
static void state_io(dfwb_io *io, void *plant)
{
    dfwb_drivetrain *p = (dfwb_drivetrain *)plant;
    dfwb_pw_io(io, &p->pw);
    dfwb_io_f64(io, &p->M1);
    dfwb_io_f64(io, &p->M2);
    dfwb_io_f64(io, &p->h);
    dfwb_io_f64(io, &p->eps);
    dfwb_io_f64(io, &p->B);
    dfwb_io_f64(io, &p->Fc);
    dfwb_io_f64(io, &p->Fs);
    dfwb_io_i64(io, &p->impacts);
    dfwb_io_int(io, &p->contact);
    dfwb_io_int(io, &p->slip);
    dfwb_io_int(io, &p->departing);
    dfwb_io_motion(io, &p->rel);
    dfwb_io_motion(io, &p->dev);
}

/* Whether search s is one the plant's mode makes (its type, sign, level and bound). */
static int known_search(const dfwb_drivetrain *p, const dfwb_search *s)
{
    if (s->bounded != (p->pw.output.lam != 0.0)) /* every search of a damped motion has a decaying bound */
        return 0;
    if (s->kind == DFWB_EVENT_BAND)
        return s->type == DFWB_SEARCH_VELOCITY && !s->has_level && s->sign == (double)p->slip && p->slip != 0;
    if (p->contact != FREE)
        return s->kind == DFWB_EVENT_RELEASE && s->type == PRESSING && !p->rigid && !s->has_level
               && s->sign == (double)side_sigma(p->contact) && p->slip != 0;
    if (s->kind == DFWB_EVENT_APEX)
        return s->type == SEPARATION && !s->has_level && s->sign == -(double)p->departing && p->departing != 0;
    if (s->kind == DFWB_EVENT_WALL_LOWER)
        return s->type == GAP && !s->has_level && s->sign == 1.0 && p->departing != -1;
    if (s->kind == DFWB_EVENT_WALL_UPPER)
        return s->type == GAP && s->has_level && s->level == p->h && s->sign == -1.0 && p->departing != 1;
    return 0;
}

/* The parameter checks, in the Python check's order: shared by the plant and its closed loop. */
static int check_parameters(dfwb_err *err, double M1, double M2, double h, double eps, double B, double Fc,
                            double Fs, double x1_0, double v1_0, double v2_0, double gap0)
{
    char rh[DFWB_REPR_SIZE], rf[DFWB_REPR_SIZE], allowed[128];
    int rc;
    if ((rc = dfwb_check(err, "M1", M1, M1 > 0.0, "M1 must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "M2", M2, M2 > 0.0, "M2 must be > 0 (kg)")) != DFWB_OK
        || (rc = dfwb_check(err, "h", h, h == 0.0 || h >= MIN_CLEARANCE,
                            "h must be 0 (rigid) or >= " MIN_CLEARANCE_TEXT " (m)")) != DFWB_OK
        || (rc = dfwb_check(err, "eps", eps, 0.0 <= eps && eps <= 1.0, "eps must be in [0, 1]")) != DFWB_OK
        || (rc = dfwb_check(err, "B", B, B >= 0.0, "B must be >= 0 (N.s/m)")) != DFWB_OK
        || (rc = dfwb_check(err, "Fc", Fc, Fc >= 0.0, "Fc must be >= 0 (N)")) != DFWB_OK)
        return rc;
    dfwb_repr(Fc, rf);
    snprintf(allowed, sizeof allowed, "Fs must be >= Fc = %s (N)", rf);
    if ((rc = dfwb_check(err, "Fs", Fs, Fs >= Fc, allowed)) != DFWB_OK)
        return rc;
    dfwb_repr(h, rh);
    snprintf(allowed, sizeof allowed, "gap0 must be in [0, h] = [0, %s] (m), or -1 in an FMU (h/2)", rh);
    if ((rc = dfwb_check(err, "gap0", gap0, 0.0 <= gap0 && gap0 <= h, allowed)) != DFWB_OK
        || (rc = dfwb_check(err, "x1_0", x1_0, 1, "x1_0 must be a finite number")) != DFWB_OK
        || (rc = dfwb_check(err, "v1_0", v1_0, 1, "v1_0 must be a finite number")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "v2_0", v2_0, 1, "v2_0 must be a finite number");
}

/* The plant's own checks of a state read into p (the common part is checked first). */
static int validate(void *plant, dfwb_err *err)
{
    dfwb_drivetrain *p = (dfwb_drivetrain *)plant;
    const dfwb_pw *pw = &p->pw;
    char message[256];
    dfwb_err local;
    int rc, i;
    dfwb_err_init(&local, message, sizeof message);
    if (check_parameters(&local, p->M1, p->M2, p->h, p->eps, p->B, p->Fc, p->Fs, 0.0, 0.0, 0.0, 0.0) != DFWB_OK)
        return dfwb_fail(err, DFWB_E_STATE, "the state's parameters are out of range: %s", message);
    p->rigid = p->h == 0.0;
    if ((rc = dfwb_state_check_int(err, "impacts", p->impacts, p->impacts >= 0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "contact", p->contact, p->rigid ? p->contact == LOWER
                                      : (p->contact == FREE || p->contact == LOWER || p->contact == UPPER),
                                      "must be 0, 1 or 2 (1 when h = 0)")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "slip", p->slip, -1 <= p->slip && p->slip <= 1, "must be -1, 0 or 1"))
               != DFWB_OK
        || (rc = dfwb_state_check_int(err, "departing", p->departing, -1 <= p->departing && p->departing <= 1
                                      && (p->contact == FREE || p->departing == 0), "must be -1, 0 or 1 (0 "
                                      "together)")) != DFWB_OK
        || (rc = dfwb_state_motion(&p->rel, "rel", &pw->drive, pw->t, err)) != DFWB_OK
        || (rc = dfwb_state_motion(&p->dev, "dev", &pw->drive, pw->t, err)) != DFWB_OK)
        return rc;
    if (p->contact != FREE && p->slip == 0
        && !(pw->nsearch == 0 && (pw->analytic_kind == DFWB_EVENT_RELEASE || pw->analytic_kind == DFWB_EVENT_BREAK_UP
                                  || pw->analytic_kind == DFWB_EVENT_BREAK_DOWN)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's stuck piece is out of range: it waits for a release or "
                         "a break-away alone");
    if ((p->contact == FREE || p->slip != 0) && !(pw->analytic_kind == 0 && isinf(pw->analytic)))
        return dfwb_fail(err, DFWB_E_STATE, "the state's moving piece is out of range: it has no analytic event");
    for (i = 0; i < pw->nsearch; i++)
        if (!known_search(p, &pw->searches[i]))
            return dfwb_fail(err, DFWB_E_STATE, "the state's search %d (kind %d) is out of range: not one its "
                             "mode makes", i, pw->searches[i].kind);
    /* derived, as the constructor computes them */
    p->total = p->M1 + p->M2;
    p->r2 = p->M2 / p->total;
    p->tol_h = 1e-12 * p->h;
    return DFWB_OK;
}

/* -- the closed loop (DrivetrainLoop of fmus/drivetrain.py): q = (x1, v1, gap, w = v2 - v1), y = x1, f on M2 --- */
/* par = {M1, M2, h, eps, B, Fc, Fs, r2, tol_h}; keys: 3 side + s + 1 (side: 0 flight, 1 lower, 2 upper) */
static int key_of(int side, int s) { return 3 * side + s + 1; }

static int loop_check(dfwb_loop *L, const double *v, double *q0, dfwb_err *err)
{
    const double M1 = v[DFWB_DRIVETRAIN_LOOP_M1], M2 = v[DFWB_DRIVETRAIN_LOOP_M2], h = v[DFWB_DRIVETRAIN_LOOP_h];
    const double eps = v[DFWB_DRIVETRAIN_LOOP_eps], B = v[DFWB_DRIVETRAIN_LOOP_B], Fc = v[DFWB_DRIVETRAIN_LOOP_Fc];
    const double Fs = v[DFWB_DRIVETRAIN_LOOP_Fs], gap0 = v[DFWB_DRIVETRAIN_LOOP_gap0];
    const double x1_0 = v[DFWB_DRIVETRAIN_LOOP_x1_0], v1_0 = v[DFWB_DRIVETRAIN_LOOP_v1_0];
    const double v2_0 = v[DFWB_DRIVETRAIN_LOOP_v2_0];
    int rc;
    if ((rc = check_parameters(err, M1, M2, h, eps, B, Fc, Fs, x1_0, v1_0, v2_0, gap0)) != DFWB_OK)
        return rc;
    L->par[0] = M1;
    L->par[1] = M2;
    L->par[2] = h;
    L->par[3] = eps;
    L->par[4] = B;
    L->par[5] = Fc;
    L->par[6] = Fs;
    L->par[7] = M2 / (M1 + M2);
    L->par[8] = 1e-12 * h;
    q0[0] = x1_0;
    q0[1] = v1_0;
    q0[2] = gap0;
    q0[3] = v2_0 - v1_0;
    return DFWB_OK;
}

static int loop_check_state(const dfwb_loop *L, const double *q, dfwb_err *err)
{
    char rh[DFWB_REPR_SIZE], allowed[96];
    dfwb_repr(L->par[2], rh);
    snprintf(allowed, sizeof allowed, "the gap must be in [0, h] = [0, %s] (m)", rh);
    return dfwb_check(err, "gap", q[2], 0.0 <= q[2] && q[2] <= L->par[2], allowed);
}

/* DrivetrainLoop.plant_mode */
static void loop_mode(const dfwb_loop *L, int key, dfwb_plant_mode *pm)
{
    const double M1 = L->par[0], M2 = L->par[1], h = L->par[2], B = L->par[4], Fc = L->par[5], Fs = L->par[6];
    const int side = key / 3, s = key % 3 - 1;
    const double sigma = side == LOWER ? -1.0 : 1.0, M = M1 + M2;
    if (side == FREE) { /* x1' = v1, v1' = -(B v1 + Fc s) / M1 (sliding), g' = w, w' = f / M2 - v1' */
        const double lam = s ? B / M1 : 0.0, a = s ? -(double)s * Fc / M1 : 0.0;
        pm->P[0][1] = 1.0;
        pm->P[1][1] = -lam;
        pm->P[2][3] = 1.0;
        pm->P[3][1] = lam;
        pm->p[1] = a;
        pm->p[3] = -a;
        pm->phi[3] = 1.0 / M2;
        dfwb_loop_add_event(pm, DFWB_EVENT_WALL_LOWER, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0);  /* g > 0 */
        dfwb_loop_add_event(pm, DFWB_EVENT_WALL_UPPER, 0.0, 0.0, -1.0, 0.0, 0.0, h);   /* h - g > 0 */
        if (s)
            dfwb_loop_add_event(pm, DFWB_EVENT_BAND, 0.0, (double)s, 0.0, 0.0, 0.0, 0.0); /* s v1 > 0 */
        return;
    }
    if (s) { /* together: M v' = f - Fc s - B v; pressing: sigma (M1 f + M2 (Fc s + B v)) > 0 */
        pm->P[0][1] = 1.0;
        pm->P[1][1] = -B / M;
        pm->p[1] = -(double)s * Fc / M;
        pm->phi[1] = 1.0 / M;
        dfwb_loop_add_event(pm, DFWB_EVENT_BAND, 0.0, (double)s, 0.0, 0.0, 0.0, 0.0); /* s v > 0 */
        if (h != 0.0)
            dfwb_loop_add_event(pm, DFWB_EVENT_RELEASE, 0.0, sigma * M2 * B, 0.0, 0.0, sigma * M1,
                                sigma * M2 * Fc * (double)s);
        return;
    }
    if (h != 0.0) { /* stuck together while sigma f > 0 (pressing) and sigma f < Fs */
        dfwb_loop_add_event(pm, DFWB_EVENT_RELEASE, 0.0, 0.0, 0.0, 0.0, sigma, 0.0);
        dfwb_loop_add_event(pm, sigma > 0 ? DFWB_EVENT_BREAK_UP : DFWB_EVENT_BREAK_DOWN, 0.0, 0.0, 0.0, 0.0, -sigma,
                            Fs);
        return;
    }
    dfwb_loop_add_event(pm, DFWB_EVENT_BREAK_UP, 0.0, 0.0, 0.0, 0.0, -1.0, Fs); /* rigid: |f| <= Fs */
    dfwb_loop_add_event(pm, DFWB_EVENT_BREAK_DOWN, 0.0, 0.0, 0.0, 0.0, 1.0, Fs);
}

/* DrivetrainLoop._rest: together at the wall at v = 0 */
static int loop_rest(dfwb_loop *L, int side, double *X, int *key, int *departing, dfwb_err *err)
{
    const int stuck_key = key_of(side, 0);
    int sign, rc;
    X[1] = 0.0;
    X[3] = 0.0;
    *departing = -1;
    if (L->par[2] == 0.0) {
        if ((rc = dfwb_hy_after(&L->hy, stuck_key, 0, X, &sign, err)) != DFWB_OK)
            return rc;
        if (sign < 0) {
            *key = key_of(side, 1);
            *departing = 0;
            return DFWB_OK;
        }
        if ((rc = dfwb_hy_after(&L->hy, stuck_key, 1, X, &sign, err)) != DFWB_OK)
            return rc;
        if (sign < 0) {
            *key = key_of(side, -1);
            *departing = 0;
            return DFWB_OK;
        }
        *key = stuck_key;
        return DFWB_OK;
    }
    if ((rc = dfwb_hy_after(&L->hy, stuck_key, 0, X, &sign, err)) != DFWB_OK)
        return rc;
    if (sign < 0) { /* pulling */
        *key = key_of(FREE, 0);
        *departing = side == LOWER ? 0 : 1;
        return DFWB_OK;
    }
    if ((rc = dfwb_hy_after(&L->hy, stuck_key, 1, X, &sign, err)) != DFWB_OK)
        return rc;
    if (sign < 0) { /* breaking away, in the direction that presses */
        *key = key_of(side, side_sigma(side));
        *departing = 0;
        return DFWB_OK;
    }
    *key = stuck_key;
    return DFWB_OK;
}

/* DrivetrainLoop._at_wall: the impact (if closing), then together or a flight away from it */
static int loop_at_wall(dfwb_loop *L, int side, double *X, int *key, int *departing, dfwb_err *err)
{
    const double M1 = L->par[0], M2 = L->par[1], h = L->par[2], eps = L->par[3], B = L->par[4], Fc = L->par[5];
    const double r2 = L->par[7], tol_h = L->par[8];
    const int sigma = side_sigma(side);
    double w, v;
    X[2] = side == LOWER ? 0.0 : h;
    w = X[3];
    if (h == 0.0) { /* rigid: plastic at once, the common velocity */
        X[1] += r2 * w;
        X[3] = w = 0.0;
    } else if ((double)sigma * w > 0.0) { /* closing: Newton's impact law, momentum kept */
        const double next = -eps * w;
        X[1] += r2 * (w - next);
        X[3] = w = next;
        L->count += 1;
    }
    v = X[1] + r2 * w;
    if (v == 0.0 && w == 0.0)
        return loop_rest(L, side, X, key, departing, err);
    if (v != 0.0) {
        const int s = sign_of(v), k = key_of(side, s);
        double Y[DFWB_HY_DIM], N;
        int press, rc, i;
        for (i = 0; i < L->m + L->order; i++)
            Y[i] = X[i];
        Y[1] = v;
        Y[3] = 0.0;
        if (h == 0.0) {
            for (i = 0; i < L->m + L->order; i++)
                X[i] = Y[i];
            *key = k;
            *departing = -1;
            return DFWB_OK;
        }
        if ((rc = dfwb_hy_after(&L->hy, k, 1, Y, &press, err)) != DFWB_OK)
            return rc;
        N = M1 * dfwb_loop_feedback(L, X) + M2 * (Fc * (double)s + B * v);
        if (press > 0 && (w == 0.0 || 0.5 * w * w * M1 * M2 <= tol_h * fabs(N))) {
            X[1] = v;
            X[3] = 0.0;
            *key = k;
            *departing = -1;
            return DFWB_OK;
        }
    }
    *key = key_of(FREE, sign_of(X[1]));
    *departing = side == LOWER ? 0 : 1;
    return DFWB_OK;
}

static int loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err)
{
    const double h = L->par[2];
    if (h == 0.0 || !(0.0 < X[2] && X[2] < h))
        return loop_at_wall(L, h == 0.0 || X[2] <= 0.0 ? LOWER : UPPER, X, key, departing, err);
    *key = key_of(FREE, sign_of(X[1]));
    *departing = -1;
    return DFWB_OK;
}

static int loop_fire(dfwb_loop *L, int kind, double *X, int *key, int *departing, dfwb_err *err)
{
    const int side = L->hy.key / 3, s = L->hy.key % 3 - 1;
    if (kind == DFWB_EVENT_BAND) {
        X[1] = 0.0;
        if (side == FREE) { /* the load stops, and sticks: nothing pushes it */
            *key = key_of(FREE, 0);
            *departing = -1;
            return DFWB_OK;
        }
        return loop_rest(L, side, X, key, departing, err);
    }
    if (kind == DFWB_EVENT_WALL_LOWER || kind == DFWB_EVENT_WALL_UPPER)
        return loop_at_wall(L, kind == DFWB_EVENT_WALL_LOWER ? LOWER : UPPER, X, key, departing, err);
    if (kind == DFWB_EVENT_RELEASE) {
        X[3] = 0.0;
        *key = key_of(FREE, s);
        *departing = side == LOWER ? 0 : 1;
        return DFWB_OK;
    }
    *key = key_of(side, kind == DFWB_EVENT_BREAK_UP ? 1 : -1); /* BREAK_UP, BREAK_DOWN */
    *departing = 0;
    return DFWB_OK;
}

static const char *const LOOP_COORDINATES[] = {"x1", "v1", "gap", "w"};

static const dfwb_loop_class LOOP = {4, 0, DFWB_LOOP_DRIVETRAIN_PARAMS, 9, "a drivetrain", LOOP_COORDINATES,
                                     "('x1', 'v1', 'gap', 'w')", loop_check, loop_check_state, loop_mode,
                                     loop_initial, loop_fire, 9, NULL, NULL, -1, NULL, 0, "DrivetrainLoop",
                                     dfwb_loop_gap_contact, dfwb_loop_gap_wall, dfwb_loop_gap_half_play};

/* -- the class ------------------------------------------------------------------------------------ */
/* Drivetrain.__init__, then PiecewisePlant's: the order of the Python constructor (gap0 given: None is h/2) */
static int init(void *plant, const double *params, dfwb_err *err)
{
    dfwb_drivetrain *p = (dfwb_drivetrain *)plant;
    const double M1 = params[DFWB_DRIVETRAIN_M1], M2 = params[DFWB_DRIVETRAIN_M2], h = params[DFWB_DRIVETRAIN_h];
    const double eps = params[DFWB_DRIVETRAIN_eps], B = params[DFWB_DRIVETRAIN_B], Fc = params[DFWB_DRIVETRAIN_Fc];
    const double Fs = params[DFWB_DRIVETRAIN_Fs], F = params[DFWB_DRIVETRAIN_F];
    const double omega = params[DFWB_DRIVETRAIN_omega], phi = params[DFWB_DRIVETRAIN_phi];
    const double x1_0 = params[DFWB_DRIVETRAIN_x1_0], v1_0 = params[DFWB_DRIVETRAIN_v1_0];
    const double v2_0 = params[DFWB_DRIVETRAIN_v2_0], gap0 = params[DFWB_DRIVETRAIN_gap0];
    const double f = params[DFWB_DRIVETRAIN_f], harmonics = params[DFWB_DRIVETRAIN_harmonics];
    int rc;
    if ((rc = check_parameters(err, M1, M2, h, eps, B, Fc, Fs, x1_0, v1_0, v2_0, gap0)) != DFWB_OK
        || (rc = dfwb_check_drive(err, F, omega, phi, f, harmonics)) != DFWB_OK)
        return rc;
    dfwb_pw_init(&p->pw, F, omega, phi, f, harmonics);
    p->M1 = M1, p->M2 = M2, p->h = h, p->eps = eps, p->B = B, p->Fc = Fc, p->Fs = Fs;
    p->total = M1 + M2;
    p->r2 = M2 / p->total; /* an impulse changing w by dw changes v1 by -r2 dw */
    p->tol_h = 1e-12 * h;
    p->rigid = h == 0.0;
    p->impacts = 0;
    p->contact = FREE;
    p->slip = 0;
    p->departing = 0;
    return dfwb_err_finish(err, start(p, 0.0, x1_0, v1_0, gap0, v2_0 - v1_0, err));
}

/* {x1, v1, x2, v2, gap} */
static void output(const void *plant, double *out)
{
    const dfwb_drivetrain *p = (const dfwb_drivetrain *)plant;
    double x1, v1, g, w;
    dfwb_motion_state(&p->pw.output, p->pw.t, &x1, &v1);
    relative(p, p->pw.t, &g, &w);
    out[0] = x1;
    out[1] = v1;
    out[2] = x1 + g;
    out[3] = v1 + w;
    out[4] = g;
}

/* 0 contact, 1 slip, 2 impacts */
static long long counter(const void *plant, size_t i)
{
    const dfwb_drivetrain *p = (const dfwb_drivetrain *)plant;
    return i == 0 ? (long long)p->contact : (i == 1 ? (long long)p->slip : p->impacts);
}

static int same(const void *one, const void *other)
{
    const dfwb_drivetrain *a = (const dfwb_drivetrain *)one, *b = (const dfwb_drivetrain *)other;
    return dfwb_same_double(a->M1, b->M1) && dfwb_same_double(a->M2, b->M2) && dfwb_same_double(a->h, b->h)
           && dfwb_same_double(a->eps, b->eps) && dfwb_same_double(a->B, b->B) && dfwb_same_double(a->Fc, b->Fc)
           && dfwb_same_double(a->Fs, b->Fs) && dfwb_same_double(a->total, b->total)
           && dfwb_same_double(a->r2, b->r2) && dfwb_same_double(a->tol_h, b->tol_h) && a->rigid == b->rigid;
}

static const dfwb_drivetrain zero_state = {0}; /* the state's size is counted on it */

const dfwb_plant_class dfwb_drivetrain_class = {
    DFWB_PLANT_DRIVETRAIN, sizeof(dfwb_drivetrain), &zero_state, offsetof(dfwb_drivetrain, pw.output), fire,
    restart, state_io, validate, DFWB_DRIVETRAIN_PARAMS, 5, 3, init, output, counter, same, &LOOP, search,
    search_bound, NULL, NULL};
