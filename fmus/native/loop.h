/* loop.h - internal: a plant in feedback with a linear controller (loops.c), and what a plant gives its loop.
 *
 * loops.c is the loop (fmus/loops.py's FeedbackLoop: the controller, the coupling, the API); each plant's
 * file gives its dfwb_loop_class (the subclass: FrictionLoop, BacklashLoop, StaticBacklashLoop), named by
 * its dfwb_plant_class. Not part of the public API (dfwb_core.h).
 */
#ifndef DFWB_LOOP_H
#define DFWB_LOOP_H

#include "dfwb_core.h"
#include "exact.h"
#include "hybrid.h"

#define DFWB_LOOP_PLANT_MAX 4 /* plant coordinates at most */
#define DFWB_LOOP_PAR 9       /* the plant's constants held by a loop */
#define DFWB_LOOP_STATE_PAR 7 /* of them, the ones its state holds (the others are derived) */
#define DFWB_LOOP_PLANT_EVENTS 3 /* a plant mode's event functions at most */
#define DFWB_LOOP_PARAMS_MAX 16  /* dfwb_loop_new's parameters of a plant at most (its class's nparams) */

typedef struct dfwb_loop_class dfwb_loop_class;

struct dfwb_loop {
    dfwb_hy hy; /* first: the hybrid solver */
    const dfwb_loop_class *cls;
    int plant;  /* DFWB_PLANT_* */
    int m, order, out;
    /* -G(s): (Ac, Bc, C, D) of LinearSystem with C and D negated; f = D y + C z as a row over the state */
    double Ac[DFWB_LOOP_MAX_ORDER][DFWB_LOOP_MAX_ORDER], Bc[DFWB_LOOP_MAX_ORDER], C[DFWB_LOOP_MAX_ORDER], D;
    double f_row[DFWB_HY_DIM];
    /* the plant's constants (its check writes them): friction {M, B, Fc, Fs}, backlash {M1, M2, h, eps, r2,
     * tol_h}, static {M, k, h} */
    double par[DFWB_LOOP_PAR];
    double bc[DFWB_LOOP_MAX_ORDER + 1], ac[DFWB_LOOP_MAX_ORDER]; /* G's b0..bn, a1..an (0 beyond n) */
    double section;                                                /* the section's level (0 without one) */
    long long count; /* the plant's counter: sticks, impacts, engagements */
    /* the compensators (fmus/compensation.py; the controller's-sign feedforward is Python's alone): the Coulomb
     * feedforward of the velocity F_hat slip(key) (has_coulomb), the integrator reset at rest, the integrator
     * deadband d (0: none) and its side band (-1 below -d, 0 within, +1 above d; the hybrid's variant); w: the
     * integrator's coordinate xi = w . z (with reset or a deadband) */
    int has_coulomb, reset, band;
    double F_hat, d, w[DFWB_LOOP_MAX_ORDER];
    /* the dither a sin(w_d t) (has_dither: a > 0): the oscillator (s, c) after z in the solver's state, from
     * (0, a); the loop's state as the API gives and takes it is m + order long, the oscillator left out */
    int has_dither;
    double a_d, w_d;
    /* the backlash inverse (has_inverse: h_hat > 0): the controller sees y + w, w the correction after the
     * dither's oscillator in the solver's state, set to half_play h_hat s where the play touches its side s (the
     * class's contact and wall), before the plant's logic */
    int has_inverse;
    double h_hat;
};

/* A plant mode: q' = P q + p + phi f, event functions Lq.q + Lf f + l0 (FeedbackLoop.plant_mode). */
typedef struct {
    double P[DFWB_LOOP_PLANT_MAX][DFWB_LOOP_PLANT_MAX], p[DFWB_LOOP_PLANT_MAX], phi[DFWB_LOOP_PLANT_MAX];
    int nev, kind[DFWB_LOOP_PLANT_EVENTS];
    double Lq[DFWB_LOOP_PLANT_EVENTS][DFWB_LOOP_PLANT_MAX], Lf[DFWB_LOOP_PLANT_EVENTS], l0[DFWB_LOOP_PLANT_EVENTS];
    /* an integrated mode (plant_mode's fifth item): the class's law(sign, q[col]) added to q'[row] */
    int nonlinear, row, col, sign;
    double feature; /* the law's velocity scale (law.scale; inf for none) */
} dfwb_plant_mode;

/* Append the event function l1 q0 + l2 q1 + l3 q2 + l4 q3 + Lf f + l0 of kind (DFWB_EVENT_*). */
void dfwb_loop_add_event(dfwb_plant_mode *pm, int kind, double l1, double l2, double l3, double l4, double Lf,
                         double l0);
/* FeedbackLoop.force: f = D y + C z at the solver's state X (y + w with a backlash inverse). */
double dfwb_loop_feedback(const dfwb_loop *L, const double *X);

/* What a plant gives its closed loop (its LOOP, a FeedbackLoop subclass beside its solver). */
struct dfwb_loop_class {
    int size;                        /* the plant's coordinates q (at most DFWB_LOOP_PLANT_MAX) */
    int out;                         /* the coordinate that is the output y */
    size_t nparams;                  /* dfwb_loop_new's parameters (DFWB_LOOP_*_PARAMS) */
    int npar;                        /* the entries of par[] it uses (a state's others must be 0) */
    const char *name;                /* "a static backlash": a state's messages */
    const char *const *coordinates;  /* the size coordinates' names */
    const char *coordinates_text;    /* "('x', 'v')" */
    /* The subclass's __init__: params checked (the plant's own dfwb_*_check), par[] and q0 written. */
    int (*check)(dfwb_loop *L, const double *params, double *q0, dfwb_err *err);
    /* check_coordinates of a given state (beyond finite), or NULL. */
    int (*check_state)(const dfwb_loop *L, const double *q, dfwb_err *err);
    void (*mode)(const dfwb_loop *L, int key, dfwb_plant_mode *pm);
    /* initial: the mode of X at t = 0 (X may be snapped); _fire: the mode after an event of kind at X. */
    int (*initial)(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err);
    int (*fire)(dfwb_loop *L, int kind, double *X, int *key, int *departing, dfwb_err *err);
    int keys; /* its mode keys are 0..keys-1 (its LOOP.KEYS, at most DFWB_HY_MODES) */
    /* The nonlinear term of its integrated modes and its slope (NULL: none), and the index in par of their
     * tolerance rtol (-1: none) */
    double (*law)(const dfwb_loop *L, int sign, double v);
    double (*law_slope)(const dfwb_loop *L, int sign, double v);
    int rtol;
    /* The plant's sliding direction in mode key (-1, 0 stuck, +1), which the Coulomb feedforward of the velocity
     * takes (NULL: a plant without friction); the event kind where it comes to rest, where the integrator reset
     * acts (0: none); the Python class's name (the refusals name it). */
    int (*slip)(int key);
    int rest_kind;
    const char *python_name;
    /* The side of the play an event of kind touches (CONTACTS: -1, +1; 0 none), the side whose wall a state sits
     * on (wall: the side at t = 0), and half the play in the output's units per unit of h (half_play); NULL: a
     * plant without a play (no backlash inverse). */
    int (*contact)(int kind);
    int (*wall)(const dfwb_loop *L, const double *X);
    double (*half_play)(const dfwb_loop *L);
};

/* The contact, wall and half_play of a play between two masses, the gap g = q[2] in [0, h = par[2]] (the two-mass
 * backlash's and the drivetrain's; backlash.c). */
int dfwb_loop_gap_contact(int kind);
int dfwb_loop_gap_wall(const dfwb_loop *L, const double *X);
double dfwb_loop_gap_half_play(const dfwb_loop *L);

#endif /* DFWB_LOOP_H */
