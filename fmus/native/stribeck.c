/* stribeck.c - the mass with Stribeck friction: a port of fmus/stribeck.py (StribeckMass, StribeckLoop) on the
 * friction mass (friction.h: its stick and breakaway, FrictionMass's) and the integrated family (integrated.h:
 * each slide a trajectory, its stop found on the way). The API is documented in dfwb_core.h.
 */
#include <math.h>
#include <stddef.h>

#include "dfwb_core.h"
#include "exact.h"
#include "friction.h"
#include "integrated.h"
#include "loop.h"
#include "plant.h"

#define FAR 1e6 /* |v| / vs beyond which exp(-(|v|/vs)^delta) is 0.0 for every delta >= 0.5 */

typedef struct {
    dfwb_friction base; /* first: the friction mass (Dv = 0), its slide this plant's */
    double vs, delta, rtol;
} dfwb_stribeck;

/* _power: w ** delta, delta = 2 as w * w */
static double power(double w, double delta) { return delta == 2.0 ? w * w : pow(w, delta); }

/* stribeck_factor: exp(-(|v|/vs)^delta), 0.0 far beyond vs */
static double factor(double v, double vs, double delta)
{
    const double w = fabs(v) / vs;
    return w > FAR ? 0.0 : exp(-power(w, delta));
}

/* StribeckSlide: (u - s (Fc + (Fs - Fc) factor) - B v) / M, the drive the plant's own */
static double law(const void *plant, int s, double t, double v)
{
    const dfwb_stribeck *p = (const dfwb_stribeck *)plant;
    const dfwb_friction *f = &p->base;
    const double friction = (double)s * (f->Fc + (f->Fs - f->Fc) * factor(v, p->vs, p->delta)) + f->B * v;
    return (dfwb_drive_u(&f->pw.drive, t) - friction) / f->M;
}

/* StribeckSlide.size: the magnitude of the acceleration's terms */
static double law_size(const void *plant, int s, double t, double v)
{
    const dfwb_stribeck *p = (const dfwb_stribeck *)plant;
    const dfwb_friction *f = &p->base;
    (void)s;
    (void)t;
    return (fabs(f->pw.drive.f) + f->pw.drive.F + f->Fc + (f->Fs - f->Fc) + f->B * fabs(v)) / f->M;
}

/* StribeckMass._slide: the trajectory from (t, x, v), its stop the piece's event */
static int slide(dfwb_friction *f, double t, double x, double v, int s, int departing, dfwb_err *err)
{
    const dfwb_stribeck *p = (const dfwb_stribeck *)f;
    (void)departing;
    (void)err;
    /* StribeckSlide.scale: vs, none without a drop */
    dfwb_pw_begin_integrated(&f->pw, t, x, v, s, p->rtol, f->Fs - f->Fc != 0.0 ? p->vs : INFINITY, DFWB_EVENT_BAND);
    return DFWB_OK;
}

/* check_stribeck, in its order */
static int check_parameters(dfwb_err *err, double M, double B, double Fc, double Fs, double vs, double delta,
                            double rtol, double x0, double v0)
{
    int rc;
    if ((rc = dfwb_friction_check_forces(err, M, B, Fc, Fs)) != DFWB_OK
        || (rc = dfwb_check(err, "vs", vs, vs > 0.0, "vs must be > 0 (m/s)")) != DFWB_OK
        || (rc = dfwb_check(err, "delta", delta, 0.5 <= delta && delta <= 10.0, "delta must be in [0.5, 10]"))
               != DFWB_OK
        || (rc = dfwb_check(err, "rtol", rtol, 1e-12 <= rtol && rtol <= 1e-3, "rtol must be in [1e-12, 1e-3]"))
               != DFWB_OK
        || (rc = dfwb_check(err, "x0", x0, 1, "x0 must be a finite number (m)")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "v0", v0, 1, "v0 must be a finite number (m/s)");
}

/* -- state as bytes ------------------------------------------------------------------------------------ */
static void state_io(dfwb_io *io, void *plant)
{
    dfwb_stribeck *p = (dfwb_stribeck *)plant;
    dfwb_friction_io(io, &p->base);
    dfwb_io_f64(io, &p->vs);
    dfwb_io_f64(io, &p->delta);
    dfwb_io_f64(io, &p->rtol);
}

static int validate(void *plant, dfwb_err *err)
{
    dfwb_stribeck *p = (dfwb_stribeck *)plant;
    dfwb_friction *f = &p->base;
    const dfwb_pw *pw = &f->pw;
    int rc;
    if ((rc = dfwb_friction_state_forces(f, err)) != DFWB_OK
        || (rc = dfwb_state_check(err, "Dv", f->Dv, f->Dv == 0.0, "must be 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "vs", p->vs, isfinite(p->vs) && p->vs > 0.0, "must be > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "delta", p->delta, 0.5 <= p->delta && p->delta <= 10.0,
                                  "must be in [0.5, 10]")) != DFWB_OK
        || (rc = dfwb_state_check(err, "rtol", p->rtol, 1e-12 <= p->rtol && p->rtol <= 1e-3,
                                  "must be in [1e-12, 1e-3]")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "mode", f->mode, f->mode == DFWB_FRICTION_HOLD
                                      || f->mode == DFWB_FRICTION_SLIDE, "must be 0 (hold) or 1 (slide)")) != DFWB_OK)
        return rc;
    /* hold: an analytic breakaway, no search, a closed form; slide: the trajectory of its direction, its stop */
    if (!(f->mode == DFWB_FRICTION_HOLD
              ? f->direction == 0 && pw->nsearch == 0 && !pw->integrated
                    && (pw->analytic_kind == DFWB_EVENT_BREAK_UP || pw->analytic_kind == DFWB_EVENT_BREAK_DOWN
                        || (isinf(pw->analytic) && pw->analytic_kind == 0))
              : (f->direction == 1 || f->direction == -1) && pw->nsearch == 1 && pw->integrated
                    && pw->traj.sign == f->direction && pw->traj.rtol == p->rtol && pw->analytic_kind == 0
                    && pw->searches[0].kind == DFWB_EVENT_BAND && pw->searches[0].t_from == pw->t_piece))
        return dfwb_fail(err, DFWB_E_STATE, "the state's piece is out of range: its searches and events do not "
                         "match its mode");
    f->edge_force = f->Fc + f->B * f->Dv;
    f->slide = slide;
    return DFWB_OK;
}

/* -- the class ------------------------------------------------------------------------------------------ */
/* StribeckMass.__init__: its checks, then FrictionMass's (passed) and PiecewisePlant's */
static int init(void *plant, const double *params, dfwb_err *err)
{
    dfwb_stribeck *p = (dfwb_stribeck *)plant;
    dfwb_friction *f = &p->base;
    const double M = params[DFWB_STRIBECK_M], B = params[DFWB_STRIBECK_B], Fc = params[DFWB_STRIBECK_Fc];
    const double Fs = params[DFWB_STRIBECK_Fs], vs = params[DFWB_STRIBECK_vs];
    const double delta = params[DFWB_STRIBECK_delta], rtol = params[DFWB_STRIBECK_rtol];
    const double F = params[DFWB_STRIBECK_F], omega = params[DFWB_STRIBECK_omega], phi = params[DFWB_STRIBECK_phi];
    const double x0 = params[DFWB_STRIBECK_x0], v0 = params[DFWB_STRIBECK_v0], fin = params[DFWB_STRIBECK_f];
    const double harmonics = params[DFWB_STRIBECK_harmonics];
    int rc;
    if ((rc = check_parameters(err, M, B, Fc, Fs, vs, delta, rtol, x0, v0)) != DFWB_OK
        || (rc = dfwb_check_drive(err, F, omega, phi, fin, harmonics)) != DFWB_OK)
        return rc;
    p->vs = vs, p->delta = delta, p->rtol = rtol;
    dfwb_pw_init(&f->pw, F, omega, phi, fin, harmonics);
    f->M = M, f->B = B, f->Fc = Fc, f->Fs = Fs, f->Dv = 0.0;
    f->edge_force = Fc + B * 0.0;
    f->mode = DFWB_FRICTION_HOLD;
    f->direction = 0;
    f->slide = slide;
    return dfwb_err_finish(err, dfwb_friction_start(f, 0.0, x0, v0, 0, err));
}

static int same(const void *one, const void *other)
{
    const dfwb_stribeck *a = (const dfwb_stribeck *)one, *b = (const dfwb_stribeck *)other;
    return dfwb_same_double(a->base.M, b->base.M) && dfwb_same_double(a->base.B, b->base.B)
           && dfwb_same_double(a->base.Fc, b->base.Fc) && dfwb_same_double(a->base.Fs, b->base.Fs)
           && dfwb_same_double(a->base.Dv, b->base.Dv) && dfwb_same_double(a->base.edge_force, b->base.edge_force)
           && dfwb_same_double(a->vs, b->vs) && dfwb_same_double(a->delta, b->delta)
           && dfwb_same_double(a->rtol, b->rtol);
}

/* -- the closed loop (StribeckLoop: FrictionLoop with each slide's Stribeck drop integrated) ----------------- */
/* StribeckLoop.__init__: {M, B, Fc, Fs, vs, delta, rtol, x0, v0}; par = {M, B, Fc, Fs, vs, delta, rtol} */
static int loop_check(dfwb_loop *L, const double *v, double *q0, dfwb_err *err)
{
    const double M = v[DFWB_STRIBECK_LOOP_M], B = v[DFWB_STRIBECK_LOOP_B], Fc = v[DFWB_STRIBECK_LOOP_Fc];
    const double Fs = v[DFWB_STRIBECK_LOOP_Fs], vs = v[DFWB_STRIBECK_LOOP_vs], delta = v[DFWB_STRIBECK_LOOP_delta];
    const double rtol = v[DFWB_STRIBECK_LOOP_rtol], x0 = v[DFWB_STRIBECK_LOOP_x0], v0 = v[DFWB_STRIBECK_LOOP_v0];
    int rc;
    if ((rc = check_parameters(err, M, B, Fc, Fs, vs, delta, rtol, x0, v0)) != DFWB_OK)
        return rc;
    L->par[0] = M;
    L->par[1] = B;
    L->par[2] = Fc;
    L->par[3] = Fs;
    L->par[4] = vs;
    L->par[5] = delta;
    L->par[6] = rtol;
    q0[0] = x0;
    q0[1] = v0;
    return DFWB_OK;
}

/* StribeckDrop: -s (Fs - Fc) / M factor(v), and its slope in v */
static double drop(const dfwb_loop *L, int s, double v)
{
    const double scale = (double)(-s) * (L->par[3] - L->par[2]) / L->par[0];
    return scale * factor(v, L->par[4], L->par[5]);
}

static double drop_slope(const dfwb_loop *L, int s, double v)
{
    const double scale = (double)(-s) * (L->par[3] - L->par[2]) / L->par[0], vs = L->par[4], delta = L->par[5];
    const double w = fabs(v) / vs;
    if (w > FAR)
        return 0.0;
    if (w == 0.0)
        return delta == 1.0 ? (double)(-s) * scale / vs : 0.0;
    return -scale * delta * pow(w, delta - 1.0) / vs * (v > 0.0 ? 1.0 : -1.0) * exp(-power(w, delta));
}

/* StribeckLoop.plant_mode: FrictionLoop's, a slide with its drop as the nonlinear term on v' of v */
static void loop_mode(const dfwb_loop *L, int key, dfwb_plant_mode *pm)
{
    dfwb_friction_loop_mode(L, key, pm);
    if (key != DFWB_LOOP_STICK) {
        pm->feature = L->par[3] - L->par[2] != 0.0 ? L->par[4] : INFINITY; /* StribeckDrop.scale */
        pm->nonlinear = 1;
        pm->row = 1;
        pm->col = 1;
        pm->sign = key == DFWB_LOOP_SLIDE_UP ? 1 : -1;
    }
}

static const char *const LOOP_COORDINATES[] = {"x", "v"};

static const dfwb_loop_class LOOP = {2, 0, DFWB_LOOP_STRIBECK_PARAMS, 7, "a Stribeck mass", LOOP_COORDINATES,
                                     "('x', 'v')", loop_check, NULL, loop_mode, dfwb_friction_loop_initial,
                                     dfwb_friction_loop_fire, 3, drop, drop_slope, 6, dfwb_friction_loop_slip,
                                     DFWB_EVENT_BAND, "StribeckLoop", NULL, NULL, NULL};

static const dfwb_stribeck zero_state; /* zeros (static): the state's size is counted on it */

const dfwb_plant_class dfwb_stribeck_class = {
    DFWB_PLANT_STRIBECK, sizeof(dfwb_stribeck), &zero_state, offsetof(dfwb_stribeck, base.pw.output),
    dfwb_friction_fire, dfwb_friction_restart, state_io, validate, DFWB_STRIBECK_PARAMS, 4, 0, init,
    dfwb_friction_output, NULL, same, &LOOP, NULL, NULL, law, law_size};
