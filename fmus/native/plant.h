/* plant.h - internal: what the plants share (errors, the event log, states as bytes, the piece machinery
 * of fmus/piecewise.py, and the API functions that are the same for every plant).
 *
 * Not part of the public API (dfwb_core.h); compiled with -fvisibility=hidden like exact.h.
 */
#ifndef DFWB_PLANT_H
#define DFWB_PLANT_H

#include <stddef.h>
#include <stdint.h>

#include "dfwb_core.h"
#include "exact.h"
#include "integrated.h"

/* -- errors ------------------------------------------------------------------------- */
void dfwb_err_init(dfwb_err *err, char *buf, size_t len);
/* The status an API call returns: an overflow first (Python raised OverflowError there), else rc. */
int dfwb_err_finish(dfwb_err *err, int rc);
/* PiecewisePlant's check(name, value, ok, allowed): DFWB_E_VALUE unless a finite number and ok. */
int dfwb_check(dfwb_err *err, const char *name, double value, int ok, const char *allowed);
/* The checks of PiecewisePlant.__init__ (F, omega, phi, f, harmonics), in its order. */
int dfwb_check_drive(dfwb_err *err, double F, double omega, double phi, double f, double harmonics);
/* The refusal of a step end before the current time t (PiecewisePlant.advance's check). */
int dfwb_check_t_end(dfwb_err *err, double t, double t_end);

/* out[4] = {f, F, omega, phi} */
void dfwb_drive_values(const dfwb_drive *d, double out[4]);

/* Little-endian integers in states as bytes. */
void dfwb_put_u64(unsigned char *p, uint64_t u);
uint64_t dfwb_get_u64(const unsigned char *p);
void dfwb_put_u32(unsigned char *p, uint32_t u);
uint32_t dfwb_get_u32(const unsigned char *p);

/* zlib.crc32 of n bytes (the states' checksum; the FMU wrapper seals its serialized states with it too). */
uint32_t dfwb_crc32(const unsigned char *p, size_t n);

/* 1 when a and b have the same bits (memcmp: -0.0 differs from 0.0, a NaN equals itself). */
int dfwb_same_double(double a, double b);

/* -- the event log (a caller-enabled, bounded buffer) ---------------------------------- */
typedef struct {
    double t;
    int kind;
} dfwb_log_entry;

typedef struct {
    dfwb_log_entry *data; /* n entries held, cap allocated */
    size_t n, cap;
    size_t capacity;      /* at most this many held; 0: the log is off */
    unsigned long long dropped; /* events not recorded since the log was enabled (full, or out of memory) */
} dfwb_log;

/* Enable with room for capacity entries (grown on demand), or disable (0: entries freed). */
void dfwb_log_enable(dfwb_log *log, size_t capacity);
/* Record an event (nothing when off; counted in dropped when full or out of memory). */
void dfwb_log_add(dfwb_log *log, double t, int kind);
/* Move up to max entries, oldest first, into t[] and kind[]; NULL arrays or max 0: count pending only. */
size_t dfwb_log_read(dfwb_log *log, double *t, int *kind, size_t max);
/* dst = an independent copy of src (its entries included); 0 when out of memory (dst then off). */
int dfwb_log_copy(dfwb_log *dst, const dfwb_log *src);
void dfwb_log_free(dfwb_log *log);

/* -- states as bytes ------------------------------------------------------------------ */
/* Header (little-endian): "DFWBSTAT", u32 ABI, u32 plant kind, u32 payload bytes, u32 CRC-32 of the
 * payload (zlib's); the payload is a fixed sequence of 8-byte little-endian fields (IEEE doubles and
 * two's complement integers), one plant kind, one length. */
#define DFWB_STATE_HEADER 24

typedef struct {
    int reading;
    unsigned char *out;       /* writing: the payload's buffer (NULL: count only) */
    const unsigned char *in;  /* reading: the payload */
    size_t len, pos;
    int bad_int;              /* reading: an integer field beyond the int range, or past the end */
} dfwb_io;

void dfwb_io_writer(dfwb_io *io, unsigned char *out);
void dfwb_io_reader(dfwb_io *io, const unsigned char *in, size_t len);
void dfwb_io_f64(dfwb_io *io, double *x);
void dfwb_io_i64(dfwb_io *io, long long *x);
void dfwb_io_int(dfwb_io *io, int *x);
/* A motion's defining fields (t0, x0, v0, lam, a, b); omega and phi are the drive's, P is recomputed. */
void dfwb_io_motion(dfwb_io *io, dfwb_motion *m);

/* "dfwb_friction", ... for a plant kind, "dfwb_friction_loop", ... for DFWB_STATE_LOOP + a plant kind */
const char *dfwb_plant_name(int kind);
const char *dfwb_event_name(int kind); /* str(EventKind): "break+", "gap 0", ...; "None" for 0 */

/* Write the header for a payload already in buf + DFWB_STATE_HEADER. */
void dfwb_state_header(unsigned char *buf, int kind, size_t payload);
/* Check a state's header, length and checksum (DFWB_E_STATE with a one-line message otherwise). */
int dfwb_state_open(const unsigned char *buf, size_t len, int kind, size_t payload, dfwb_err *err);
/* DFWB_E_ARGUMENT unless a buffer of buflen bytes holds needed. */
int dfwb_state_buffer(size_t needed, size_t buflen, dfwb_err *err);

/* DFWB_E_STATE "the state's <name> = <value> is out of range: <allowed>" unless ok. */
int dfwb_state_check(dfwb_err *err, const char *name, double value, int ok, const char *allowed);
int dfwb_state_check_int(dfwb_err *err, const char *name, long long value, int ok, const char *allowed);
/* Drive, harmonics, time and events of a state; t must lie in [0, inf) with its phase in the limit. */
int dfwb_state_check_common(const dfwb_drive *d, int harmonics, double t, long long events, dfwb_err *err);
/* The Fourier integrals: finite, zero beyond harmonics. */
int dfwb_state_check_integrals(const dfwb_cx *integrals, int harmonics, dfwb_err *err);
/* A motion: six finite fields, lam >= 0, 0 <= t0 <= t; then its P is recomputed from the drive. */
int dfwb_state_motion(dfwb_motion *m, const char *name, const dfwb_drive *d, double t, dfwb_err *err);
/* The piece's times: 0 <= t_piece <= t, max(t_piece, t) <= searched <= t + period, analytic >= t_piece
 * (or +inf), found in [t_piece, searched]. */
int dfwb_state_check_piece(double t, double period, double t_piece, double searched, double analytic,
                           int has_found, double found_t, dfwb_err *err);

/* -- the piece machinery (fmus/piecewise.py) ------------------------------------------------ */
enum { DFWB_SEARCH_VELOCITY = 1, DFWB_SEARCH_POSITION = 2, DFWB_SEARCH_EDGE = 3, DFWB_SEARCH_TRAJECTORY = 4 };
#define DFWB_SEARCH_PLANT 8 /* types from here on are the plant's own (its class's search function) */
#define DFWB_MAX_SEARCHES 3

/* A pending search on the plant's subject motion (the mass, the gap):
 *   VELOCITY (VelocitySearch): g = sign v (level + sign v when has_level: the offset), g' = sign v'
 *   POSITION (PositionSearch): g = x, g' = v; with has_level (a wall): g = level - x, g' = -v
 *   EDGE (EdgeSearch):         g = sign (level - x), g' = -sign v
 *   TRAJECTORY (a Search with K None): the stop of the piece's integrated trajectory (pw->traj), found by
 *              integrating it (dfwb_traj_first_zero), no further than the step containing the advance's end
 *   DFWB_SEARCH_PLANT and above: the plant's own, evaluated by its class's search function (sign, level and
 *   has_level are the plant's to use; sign is +-1, the state's check asks)
 * with |g''| <= K (a number) or, when bounded, a function of t (K is then 0): for a VELOCITY search the
 * subject's curvature bound on [t, inf) (CurvatureBound), for the plant's own its class's search_bound;
 * from t_from; kind: its event. */
typedef struct {
    int type;
    double sign, level;
    int has_level;
    double K;
    int bounded;
    double t_from;
    int kind;
} dfwb_search;

typedef struct dfwb_plant_class dfwb_plant_class;

typedef struct {
    const dfwb_plant_class *cls; /* the plant's class (not state: set when the instance is made) */
    dfwb_drive drive;
    double period;
    int harmonics;
    double t;
    long long events;
    dfwb_cx integrals[DFWB_HARMONICS_MAX + 1];
    /* bounds on the errors of integrated pieces (PiecewisePlant's _integral_error, _position_error,
     * _velocity_error: 0 for a plant of closed forms) */
    double integral_error, position_error, velocity_error;
    /* the piece: its output is the motion, or (integrated) the trajectory */
    double t_piece;
    dfwb_motion output;
    int integrated;
    dfwb_trajectory traj;
    double analytic;
    int analytic_kind;
    int nsearch;
    dfwb_search searches[DFWB_MAX_SEARCHES];
    double searched;
    int has_found;
    double found_t;
    int found_kind;
    /* not state: first_root's workspace and the caller's event log */
    dfwb_stack stack;
    dfwb_log log;
} dfwb_pw;

/* Apply an event at t; *counted = whether it changes the motion (PiecewisePlant._fire's return). */
typedef int (*dfwb_fire_fn)(void *plant, double t, int kind, int *counted, dfwb_err *err);
/* Start a new piece at t from the current state (PiecewisePlant._restart, after an input change). */
typedef int (*dfwb_restart_fn)(void *plant, double t, dfwb_err *err);

void dfwb_pw_init(dfwb_pw *pw, double F, double omega, double phi, double f, double harmonics);
/* _begin: a piece from t with the output's motion and an analytic event (inf, 0: none); no search yet. */
void dfwb_pw_begin(dfwb_pw *pw, double t, const dfwb_motion *output, double analytic, int analytic_kind);
/* _begin of a piece whose output is a trajectory (its class's law of direction sign and velocity scale, from
 * (t, x, v), the velocity's error carried in) with no analytic event and its stop as the one search, of event
 * kind. */
void dfwb_pw_begin_integrated(dfwb_pw *pw, double t, double x, double v, int sign, double rtol, double scale,
                              int kind);
/* The output's position and velocity at t (the motion's, or the trajectory's: DFWB_E_VALUE out of its step),
 * and its acceleration there. */
int dfwb_pw_state(const dfwb_pw *pw, double t, double *x, double *v, dfwb_err *err);
double dfwb_pw_acceleration(const dfwb_pw *pw, double t, double v);
/* PiecewisePlant.integrals_error: a bound on the error of every running integral (0: closed forms). */
double dfwb_pw_integrals_error(const dfwb_pw *pw);
/* _set_searches(t, []): the searches are then added in order. */
void dfwb_pw_set_searches(dfwb_pw *pw, double t);
void dfwb_pw_add_search(dfwb_pw *pw, int type, double sign, int has_level, double level, double K, int bounded,
                        double t_from, int kind);
void dfwb_pw_close_piece(dfwb_pw *pw, double t, dfwb_err *err);
void dfwb_pw_integrals(const dfwb_pw *pw, double *re, double *im, dfwb_err *err);
/* PiecewisePlant.advance: subject is the motion the searches look at (a stable address in the plant). */
int dfwb_pw_advance(dfwb_pw *pw, double t_end, const dfwb_motion *subject, dfwb_fire_fn fire, void *plant,
                    dfwb_err *err);
/* PiecewisePlant.set_input. */
int dfwb_pw_set_input(dfwb_pw *pw, double f, dfwb_restart_fn restart, void *plant, dfwb_err *err);
/* The drive's F, omega and phi, the period and the harmonics of a and b have the same bits. */
int dfwb_pw_same_parameters(const dfwb_pw *a, const dfwb_pw *b);

/* The common part of a state: written (canonical: unused searches and a missing found as zeros, *pw left
 * as it is) or read. */
void dfwb_pw_io(dfwb_io *io, dfwb_pw *pw);
/* Check the common part read from a state (drive, times, integrals, output, search fields); the plant
 * checks its kinds. *pw is then usable (P recomputed, no workspace, log off). */
int dfwb_pw_validate(dfwb_pw *pw, dfwb_err *err);

/* -- a plant: a struct whose first member is its dfwb_pw, and its class ------------------------------ */
struct dfwb_plant_class {
    int kind;              /* DFWB_PLANT_*: its states' header, its name in messages */
    size_t size;           /* sizeof the plant's struct */
    const void *zero;      /* a zeroed instance (static const): the state's size is counted on it */
    size_t subject;        /* offsetof the motion its searches look at */
    dfwb_fire_fn fire;
    dfwb_restart_fn restart;
    /* The state's fields, dfwb_pw_io first; writing leaves the plant as it is. */
    void (*io)(dfwb_io *io, void *plant);
    /* The plant's own checks of a state read into it (after dfwb_pw_validate): DFWB_E_STATE when refused;
     * then it is usable (derived constants computed, every motion's P recomputed). */
    int (*validate)(void *plant, dfwb_err *err);
    size_t nparams;        /* the length of dfwb_plant_new's array (dfwb_plants.h) */
    size_t noutputs;       /* the length of dfwb_plant_output's array */
    size_t ncounters;      /* the plant's counters beyond events (dfwb_plant_counter) */
    /* Make the zeroed plant (its pw.cls set) the one at t = 0 from params[nparams], checked in its Python
     * constructor's order; on refusal dfwb_plant_new frees it. */
    int (*init)(void *plant, const double *params, dfwb_err *err);
    void (*output)(const void *plant, double *out);
    long long (*counter)(const void *plant, size_t i);
    /* The plant's own fixed parameters (and what is derived from them) of a and b have the same bits. */
    int (*same)(const void *a, const void *b);
    const struct dfwb_loop_class *loop; /* its closed loop (loop.h), or NULL: none */
    /* g and g' of a search of the plant's own type (>= DFWB_SEARCH_PLANT) at t, or NULL: it has none */
    void (*search)(const void *plant, const dfwb_search *s, double t, double *g, double *dg);
    /* |g''| on [t, inf) of such a search when it is bounded, or NULL: none of its searches is */
    double (*search_bound)(const void *plant, const dfwb_search *s, double t);
    /* The acceleration of its integrated slides (direction s) and the magnitude of its terms, or NULL: a plant
     * of closed forms (.integrated's law and law.size) */
    dfwb_law_fn law, law_size;
};

/* The class of a plant kind (DFWB_PLANT_*), NULL for a kind the core does not know. */
const dfwb_plant_class *dfwb_plant_class_of(int kind);

/* The public dfwb_plant is any plant's struct, seen through its first member. */
struct dfwb_plant {
    dfwb_pw pw;
};

/* The classes of the core's plants (each plant's file defines its own: dfwb_plants.h lists them). */
#define DFWB_CLASS_DECLARATION(kind, name) extern const dfwb_plant_class dfwb_##name##_class;
DFWB_PLANTS(DFWB_CLASS_DECLARATION)
#undef DFWB_CLASS_DECLARATION

#endif /* DFWB_PLANT_H */
