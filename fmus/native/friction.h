/* friction.h - internal: the friction mass (friction.c) as the base of a plant built on it.
 *
 * fmus/friction.py's FrictionMass and FrictionLoop are subclassed in Python (the Stribeck mass keeps their stick
 * and breakaway and replaces the slide). In C such a plant's struct starts with a dfwb_friction whose slide hook
 * is its own slide; the functions below are the friction mass's, which it calls as Python calls the base class's.
 *
 * Not part of the public API (dfwb_core.h).
 */
#ifndef DFWB_FRICTION_H
#define DFWB_FRICTION_H

#include "loop.h"
#include "plant.h"

enum { DFWB_FRICTION_HOLD, DFWB_FRICTION_SLIDE, DFWB_FRICTION_PUSH };

typedef struct dfwb_friction dfwb_friction;

/* A slide in direction s from (t, x, v) (mode and direction already set): FrictionMass._slide's override. */
typedef int (*dfwb_friction_slide_fn)(dfwb_friction *p, double t, double x, double v, int s, int departing,
                                      dfwb_err *err);

struct dfwb_friction {
    dfwb_pw pw; /* first: the piece machinery (its output, x, is also the searches' subject) */
    double M, B, Fc, Fs, Dv, edge_force;
    int mode, direction;
    dfwb_friction_slide_fn slide; /* not state: NULL for the friction mass, its own slide for a derived plant */
};

/* check_forces: M, B, Fc, Fs, in order, refused with the Python texts (DFWB_E_VALUE). */
int dfwb_friction_check_forces(dfwb_err *err, double M, double B, double Fc, double Fs);
/* The same constants read from a state (DFWB_E_STATE). */
int dfwb_friction_state_forces(const dfwb_friction *p, dfwb_err *err);

/* FrictionMass._start, _fire, _restart, output: the class's functions, for a derived plant's class. */
int dfwb_friction_start(dfwb_friction *p, double t, double x, double v, int at_edge, dfwb_err *err);
int dfwb_friction_fire(void *plant, double t, int kind, int *counted, dfwb_err *err);
int dfwb_friction_restart(void *plant, double t, dfwb_err *err);
void dfwb_friction_output(const void *plant, double *out);
/* The friction mass's state fields (dfwb_pw_io first; M, B, Fc, Fs, Dv, mode, direction). */
void dfwb_friction_io(dfwb_io *io, void *plant);

/* FrictionLoop's plant_mode, initial and _fire (par = {M, B, Fc, Fs, ...}). */
void dfwb_friction_loop_mode(const dfwb_loop *L, int key, dfwb_plant_mode *pm);
int dfwb_friction_loop_initial(dfwb_loop *L, double *X, int *key, int *departing, dfwb_err *err);
int dfwb_friction_loop_fire(dfwb_loop *L, int kind, double *X, int *key, int *departing, dfwb_err *err);
int dfwb_friction_loop_slip(int key);

#endif /* DFWB_FRICTION_H */
