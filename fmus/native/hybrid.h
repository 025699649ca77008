/* hybrid.h - internal: exact integration of a piecewise-affine hybrid system (a port of fmus/hybrid.py).
 *
 * X' = A X + c in each mode, events where an event function L.X + l0 falls to zero. Pieces are walked in
 * chunks of length h (rho h <= 1, rho a balanced norm of A) on which the state is its Taylor series; each
 * event function is a polynomial in the chunk's time whose first zero is found by dfwb_first_root from a
 * rigorous bound on its second derivative (see the header comment of fmus/hybrid.py). Same operation
 * order, same bounds and same refusal texts as the Python HybridSolver, Mode, Polynomial and trend.
 *
 * A dfwb_hy is the first member of its system's struct (a loop of loops.c), which gives its modes
 * (system: A, c and the event functions of a mode key) and its switching logic (fire).
 *
 * Not part of the public API (dfwb_core.h); compiled with -fvisibility=hidden like exact.h.
 */
#ifndef DFWB_HYBRID_H
#define DFWB_HYBRID_H

#include <stddef.h>

#include "exact.h"
#include "plant.h"

#define DFWB_HY_DIM 15 /* the state's size at most: 4 plant coordinates + 8 controller states + a dither's 2 + a
                         * backlash inverse's correction */
#define DFWB_HY_EVENTS 7        /* event functions of a mode at most: 3 of the plant, a deadband's 2, the section's 2 */
#define DFWB_HY_KEYS 9          /* mode keys 0..8 */
#define DFWB_HY_VARIANTS 3      /* the system's discrete states beside the key (a loop's deadband side) */
#define DFWB_HY_MODES (DFWB_HY_KEYS * DFWB_HY_VARIANTS) /* mode key k of variant v is slot k + DFWB_HY_KEYS v */
#define DFWB_HY_MAX_TERMS 40    /* MAX_TERMS */
#define DFWB_HY_EVENTS_PER_CHUNK 10000
#define DFWB_HY_TIME_LIMIT 1e12
#define DFWB_HY_NILPOTENT_CHUNK 1048576.0 /* NILPOTENT_CHUNK = 2 ** 20 s */
#define DFWB_HY_MAX_STATE 1e150 /* MAX_STATE */
#ifndef DFWB_HY_MAX_CHUNKS_PER_STEP /* MAX_CHUNKS_PER_STEP; -D at build time sets a smaller bound (tests) */
#define DFWB_HY_MAX_CHUNKS_PER_STEP 10000000
#endif
#define DFWB_HY_SECTION_UP 101   /* "section+": an upward crossing of the watched function (not an event) */
#define DFWB_HY_SECTION_DOWN 102 /* "section-" */

/* An event function: the event ``kind`` (DFWB_EVENT_* or a section) where L.X + l0 falls to zero. */
typedef struct {
    int kind;
    double L[DFWB_HY_DIM];
    double l0;
} dfwb_hy_event;

/* Mode: X' = A X + c, its event functions, and what is derived from them once (Mode.__init__). */
typedef struct {
    int key, n, nev;
    double A[DFWB_HY_DIM][DFWB_HY_DIM], c[DFWB_HY_DIM];
    dfwb_hy_event ev[DFWB_HY_EVENTS];
    double h, resolution;               /* the chunk; the time scale the mode resolves (Mode.resolution) */
    int terms;
    double scale[DFWB_HY_DIM];
    double absA[DFWB_HY_DIM][DFWB_HY_DIM];
    double psi[DFWB_HY_DIM][DFWB_HY_DIM];
    double rows[DFWB_HY_EVENTS][DFWB_HY_MAX_TERMS][DFWB_HY_DIM];
    double abs_rows[DFWB_HY_EVENTS][DFWB_HY_MAX_TERMS][DFWB_HY_DIM];
    double reach[DFWB_HY_EVENTS][DFWB_HY_DIM];
    double norms[DFWB_HY_EVENTS];
    double tail, curvature_tail;
    /* an integrated mode (integrated.py's IntegratedMode): law(sign, X[col]) added to X'[row]; its terms are 2
     * (the Taylor coefficients of its trend), its h the largest step (max_step) */
    int integrated, row, col, sign;
    double max_step, feature; /* its largest step; the law's velocity scale (law.scale) */
} dfwb_hy_mode;

struct dfwb_hy;

/* A, c and the system's event functions of mode ``key`` into mode (n, A, c, nev, ev; the section's are added
 * after them by the solver). */
typedef int (*dfwb_hy_system_fn)(struct dfwb_hy *hy, int key, dfwb_hy_mode *mode, dfwb_err *err);
/* At an event: X (modifiable) at t; sets the next mode key and the departing event function (-1: none). */
typedef int (*dfwb_hy_fire_fn)(struct dfwb_hy *hy, double t, int kind, double *X, int *key, int *departing,
                               dfwb_err *err);

/* The nonlinear term of an integrated mode and its slope, at the value v of the mode's column. */
typedef double (*dfwb_hy_law_fn)(const struct dfwb_hy *hy, int sign, double v);

typedef struct dfwb_hy {
    dfwb_hy_system_fn system;
    dfwb_hy_fire_fn fire;
    dfwb_hy_law_fn law, law_slope; /* NULL: no integrated mode */
    double rtol;                   /* the integrated modes' tolerance */
    int n;                              /* the state's size */
    double t;
    long long events;
    dfwb_hy_mode *modes[DFWB_HY_MODES]; /* built on demand (HybridSolver.mode); NULL: not yet */
    int variant; /* the system's discrete state beside the key (0 without one): the modes of slot DFWB_HY_SLOT */
    int has_section;
    double section_L[DFWB_HY_DIM], section_l0;
    int watching;                       /* DFWB_HY_SECTION_UP or _DOWN (with a section) */
    double time_rounding;
    /* the piece and its chunk */
    int key;
    int ndeparting, departing[2];
    double a, b, X[DFWB_HY_DIM], dX[DFWB_HY_DIM];
    int first, searched, has_event;
    double event_tau;
    int event_kind;
    /* an integrated mode's chunk, one step from (a, X, dX): its length, its end's state and derivative, the
     * second derivatives at both ends, the next step's trial size, the piece's peaks (IntegratedMode.take);
     * zeros in a closed-form mode */
    double step_h, X1[DFWB_HY_DIM], dX1[DFWB_HY_DIM], d20[DFWB_HY_DIM], d21[DFWB_HY_DIM], next_h;
    double peak[DFWB_HY_DIM];
    int stopped;                        /* the event kind the last advance stopped at (not state), 0: none */
    /* the upward crossings of the section not read yet: (t, X[n]) each */
    double *crossings;
    size_t ncrossings, crossings_cap;
    unsigned long long crossings_dropped;
    /* not state: first_root's workspace and the caller's event log */
    dfwb_stack stack;
    dfwb_log log;
} dfwb_hy;

/* The slot in modes[] of mode key ``key`` at the system's current variant. */
#define DFWB_HY_SLOT(hy, key) ((key) + DFWB_HY_KEYS * (hy)->variant)

/* The solver at t = 0 (HybridSolver.__init__): section_L NULL for none. */
void dfwb_hy_init(dfwb_hy *hy, int n, dfwb_hy_system_fn system, dfwb_hy_fire_fn fire, const double *section_L,
                  double section_l0);
/* HybridSolver.mode: the mode of ``key`` at the current variant (built when new), NULL on a refusal. */
dfwb_hy_mode *dfwb_hy_mode_of(dfwb_hy *hy, int key, dfwb_err *err);
/* HybridSolver.after: the sign of event function ``index`` of mode ``key`` just after X (its trend). */
int dfwb_hy_after(dfwb_hy *hy, int key, int index, const double *X, int *sign, dfwb_err *err);
/* HybridSolver.start: begin at t0 in mode ``key`` (departing: an index, or -1). */
int dfwb_hy_start(dfwb_hy *hy, double t0, const double *X0, int key, int departing, dfwb_err *err);
/* HybridSolver.advance, stopping early at the section's next upward crossing (stop_section) or after the first
 * event of kind (DFWB_EVENT_*, below 32) fired from mode key where bit kind of stop_events[key] is set
 * (stop_events: DFWB_HY_KEYS masks, or NULL: none); budget_left NULL: unbounded, else the chunks left
 * (decremented; below 0 refused). */
int dfwb_hy_advance(dfwb_hy *hy, double t_end, int stop_section, const unsigned int *stop_events,
                    long long *budget_left, long long budget_total, dfwb_err *err);
/* HybridSolver.state: X at hy->t. */
void dfwb_hy_state(const dfwb_hy *hy, double *X);
/* Deep copy (its own modes, crossings, log; a fresh workspace); 0 when out of memory (dst then freed). */
int dfwb_hy_copy(dfwb_hy *dst, const dfwb_hy *src);
void dfwb_hy_free(dfwb_hy *hy);
/* After a state was read into hy (t, key, watching, time_rounding, departing, a, X, the search flags and the
 * pending event; the current mode built): check them against the mode (DFWB_E_STATE) and recompute the
 * chunk's X' and end. */
int dfwb_hy_resume(dfwb_hy *hy, dfwb_err *err);

#endif /* DFWB_HYBRID_H */
