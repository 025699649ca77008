/* integrated.h - internal: the integrated solver family (a port of fmus/integrated.py).
 *
 * A trajectory x' = v, v' = law(t, v) integrated by DOPRI5(4) from a piece's start to its stop (the velocity
 * falling to zero in the direction of motion), keeping only its last step; and the Dormand-Prince tableau,
 * the dense outputs and Illinois's refinement, which the closed loops' integrated modes (hybrid.c) share.
 * Same operation order, bounds and refusal texts as the Python Trajectory and IntegratedMode.
 *
 * Not part of the public API (dfwb_core.h); compiled with -fvisibility=hidden like exact.h.
 */
#ifndef DFWB_INTEGRATED_H
#define DFWB_INTEGRATED_H

#include "dfwb_core.h"
#include "exact.h"

#define DFWB_IN_STEPS_PER_PERIOD 32.0
#define DFWB_IN_MAX_REJECTIONS 60
#define DFWB_IN_MAX_STEPS 1000000
#define DFWB_IN_STIFF_STEPS 15
#define DFWB_IN_STIFF_FRACTION 1e-3
#define DFWB_IN_STEP_FLOOR 64.0
#define DFWB_IN_SAFETY 0.9
#define DFWB_IN_GROW 5.0
#define DFWB_IN_SHRINK 0.2
#define DFWB_IN_ROUNDING (64.0 * DFWB_EPS)
#define DFWB_IN_EVENT_SAMPLES 8
#define DFWB_IN_REFINE_ITERATIONS 200
#define DFWB_IN_GAUSS 9
#define DFWB_IN_NEAR 3.0 /* NEAR: the law's feature within NEAR scales of zero */

/* The tableau (integrated.py's C, A, E, D) and the 9-point Gauss-Legendre rule on [0, 1]. */
extern const double dfwb_in_c[7], dfwb_in_a[7][6], dfwb_in_e[7], dfwb_in_d[7];
#define DFWB_IN_GAUSS_PAIRS 4 /* the rule's pairs mid -+ z half (the centre node is the next) */
extern double dfwb_in_gauss_nodes[DFWB_IN_GAUSS], dfwb_in_gauss_weights[DFWB_IN_GAUSS],
    dfwb_in_gauss_roots[DFWB_IN_GAUSS]; /* roots z of P_9, descending: nodes (1 - z) / 2 */
/* Compute the Gauss rule as _gauss_legendre does (once; idempotent). */
void dfwb_in_setup(void);

/* y0 + the quintic Hermite of a step, c = (y1 - y0, h y0', h^2 y0'', h y1', h^2 y1''), at theta. */
double dfwb_in_quintic(double y0, const double c[5], double theta);
/* y0 + theta (r0 + (1 - theta) (r1 + theta (r2 + (1 - theta) r3))): contd5's dense output. */
double dfwb_in_poly(double y0, const double r[4], double theta);
/* _ratio: |error| / scale (0 for no error, inf for no tolerance). */
double dfwb_in_ratio(double error, double scale);
/* _controlled: from trial size *h, the first step from a whose attempt(ctx, h) (its error ratio; the stages
 * left in ctx) is at most 1, *factor the next step's; DFWB_E_VALUE "the integrated <what> at t = ... (<why>)"
 * below STEP_FLOOR ulp of the time. */
typedef double (*dfwb_in_attempt)(void *ctx, double h);
int dfwb_in_control(dfwb_in_attempt attempt, void *ctx, double a, double *h, double *factor, const char *what,
                    const char *why, dfwb_err *err);
/* The zero of fun in (lo, hi], fun(lo) = g_lo > 0 >= fun(hi) = g_hi: Illinois (_illinois_fn). */
typedef double (*dfwb_in_fun)(const void *ctx, double theta);
double dfwb_in_illinois(dfwb_in_fun fun, const void *ctx, double lo, double g_lo, double hi, double g_hi);
/* _stop: the first stop of an event function over a step (1, *theta in [0, limit]) or none (0): a fall to
 * zero counts once the function rose above floor_g in the step; below -floor_g always (refined from the last
 * positive sample; none: at the start, or at the sample where the step may not stop at its start, !left). */
int dfwb_in_stop(dfwb_in_fun fun, const void *ctx, double g0, double floor_g, double limit, int left,
                 double *theta);
/* Python's max(a, b, c): the first of the largest; min(a, b, c): the first of the smallest. */
double dfwb_in_max3(double a, double b, double c);
double dfwb_in_min3(double a, double b, double c);
/* _feature_step: the largest step from velocity v at rate that resolves the law's feature at scale. */
double dfwb_in_feature_step(double scale, double v, double rate);

/* The acceleration of a slide of direction s, and the magnitude of its terms (the error control's floor). */
typedef double (*dfwb_law_fn)(const void *plant, int s, double t, double v);

typedef struct {
    int sign, harmonics;
    double t0, x0, v0, omega, rtol, scale, max_step, h, k_last, peak[2], error[2];
    int has_stopped;
    double stopped;
    long long taken;
    int stiff[2];
    /* the last step: [a, a + h], d = x - x0 from d0 and v from v0 by their dense coefficients, the integrals
     * of x from t0 to a, the bound on int |err d| from t0 to a, the bound on |err d| within the step */
    double a, sh, d0, sv0, quintic[5], vc[4];
    dfwb_cx integrals[DFWB_HARMONICS_MAX + 1];
    double int_err, pos_err;
} dfwb_trajectory;

/* Trajectory.__init__ (k_last = law(t0, v0)). */
void dfwb_traj_init(dfwb_trajectory *tr, dfwb_law_fn law, const void *plant, double t0, double x0, double v0,
                    int sign, double omega, int harmonics, double rtol, double scale, double v_error);
/* Trajectory.first_zero: *found = 1 and *t the stop when it is <= hi, integrating on to the step containing hi. */
int dfwb_traj_first_zero(dfwb_trajectory *tr, dfwb_law_fn law, dfwb_law_fn size, const void *plant, double lo,
                         double hi, int *found, double *t, dfwb_err *err);
/* x, v at t (within the last step, else DFWB_E_VALUE naming it). */
int dfwb_traj_state(const dfwb_trajectory *tr, double t, double *x, double *v, dfwb_err *err);
/* out[0..harmonics]: the integrals of x from t0 to t (out[0] = (int x, 0.0)). */
int dfwb_traj_integrals(const dfwb_trajectory *tr, double t, dfwb_cx *out, dfwb_err *err);
double dfwb_traj_integral_error(const dfwb_trajectory *tr, double t);
double dfwb_traj_position_error(const dfwb_trajectory *tr);
double dfwb_traj_velocity_error(const dfwb_trajectory *tr, double t);

#endif /* DFWB_INTEGRATED_H */
