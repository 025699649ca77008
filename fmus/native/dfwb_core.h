/* dfwb_core.h - the exact plant solvers of dfwb in C99: the public API.
 *
 * Faithful ports of the pure-Python solvers, which stay the oracles: the friction mass (fmus/friction.py),
 * the two-mass backlash (fmus/backlash.py) and the static backlash (fmus/static_backlash.py), with the
 * machinery they share (fmus/exact.py, fmus/piecewise.py). The same closed forms, the same event
 * searches, the same bounds on every loop, the same operation order (complex arithmetic mirrors
 * CPython's, libm is called where Python calls it), so that both agree to rounding - in practice bit
 * for bit.
 *
 *   friction:        M x'' + Ff = u(t),   u = f + F cos(omega t + phi)
 *     Sliding (|v| > Dv): Ff = Fc sgn(v) + B v; Dv = 0 sticks at v = 0 while |u| <= Fs, Dv > 0 is
 *     Karnopp's band (see fmus/friction.py).
 *   backlash:        M2 carries u, M1 is free, the gap g = x2 - x1 stays in [0, h]; impacts of
 *     restitution eps; a pressed bounce lower than 1e-12 h ends in contact (see fmus/backlash.py).
 *   static backlash: M x'' = u drives a play of width h and slope k, output y (see fmus/static_backlash.py).
 *
 * Conventions
 * -----------
 * - Every function that can refuse returns an int status (DFWB_OK = 0) and,
 *   when err is not NULL and errlen > 0, writes a one-line, NUL-terminated
 *   message into err (truncated to errlen): the text of the Python
 *   PlantError (floats written as Python's repr writes them).
 * - No global mutable state: one instance per solver, re-entrant;
 *   instances may be used from different threads, one thread at a time each.
 * - No exit, abort or output. Memory: malloc/realloc/free only, owned by the instance.
 * - After a refusal of set_input or advance the instance is valid but its
 *   state is unspecified (as in Python, where the step stops half way):
 *   an importer restores a copy (dfwb_plant_copy, dfwb_plant_from_bytes) or starts anew.
 * - One API for every plant (ABI 7): dfwb_plant_new(kind, ...) makes any plant's solver, the other
 *   dfwb_plant_* functions take the instance, whose kind it knows; the loops have dfwb_loop_*.
 * - Event log: off by default; dfwb_*_log(p, capacity) records (t, DFWB_EVENT_*) of every counted
 *   event (what PiecewisePlant.event_log records), at most capacity entries held (then counted in
 *   dfwb_*_log_dropped); dfwb_*_log_read moves them out. The log never changes the solution.
 * - State as bytes: dfwb_*_to_bytes writes the instance's state (a header - "DFWBSTAT", the ABI, the
 *   plant kind, the payload length, a CRC-32 - then fixed little-endian fields); dfwb_*_from_bytes
 *   makes a new instance from such bytes, checking everything it reads (header, length, checksum, every
 *   field's range, the piece's times against the current time and the phase limit) and refusing with
 *   DFWB_E_STATE otherwise. Crafted bytes that pass cannot read or write out of bounds, and a step from
 *   them stays within the bounds of every step (events per period, evaluations per search, search
 *   chunks from the current time to a phase-limited end): at worst they give wrong but well-formed
 *   numbers, as a crafted parameter would. The event log is not part of the state.
 * - Fixed parameters: dfwb_*_same_parameters(a, b) is 1 when two instances of a plant hold bit-identical
 *   fixed parameters - what a run never changes: the plant's constants and what is derived from them,
 *   the drive's F, omega and phi, the period, the harmonics; not the input f nor the state - and 0
 *   otherwise (or when either is NULL). An importer restoring a state checks it against a new instance
 *   made from the state's parameter values.
 *
 * Parameters of dfwb_plant_new and dfwb_loop_new: in the orders of dfwb_plants.h
 * (DFWB_FRICTION_Fc is Fc's index, ...), written into every build from the plants' tables
 * (fmus/table.py, where their defaults, units and ranges live). Ranges: friction M > 0 (kg), B >= 0 (N.s/m),
 * Fc >= 0 (N), Fs >= Fc (N), Dv >= 0 (m/s); backlash M1, M2 > 0 (kg), h >= 1e-290 (m), eps in [0, 1],
 * gap0 in [0, h] (Python's gap0=None is h/2: pass 0.5 * h); static backlash M, k, h > 0; everywhere
 * F finite (N), omega > 0 (rad/s), |phi| <= 1e10 (rad), initial values and f finite, harmonics an integer
 * in 0..10 (passed as a double). They are checked in the order of the Python constructor (the plant's
 * constants, its initial values, then F, omega, phi, f, harmonics): the first refused one is named.
 *
 * The exact closed loops (ABI 4; ports of fmus/loops.py and fmus/hybrid.py, the Python oracles): a plant
 * in feedback with a proper linear controller, f = -G(s) y, G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1)
 * + ... + an), n = 1..8, realised as LinearSystem realises it (controllable canonical form, state z). The
 * loop's state X is the plant's coordinates q followed by z: friction q = (x, v), y = x; backlash
 * q = (x1, v1, gap, w = v2 - v1), y = x1, f on M2; static backlash q = (x, v, y), y = q[2]. Each plant
 * mode makes the loop X' = A X + c, walked exactly in Taylor chunks with certified event searches (see
 * fmus/hybrid.py). Same chunks, bounds, refusals (texts) and operation order as Python: bit-identical.
 * See dfwb_loop_new below for the parameters.
 */
#ifndef DFWB_CORE_H
#define DFWB_CORE_H

#include <stddef.h>

#include "dfwb_plants.h"

#ifdef __cplusplus
extern "C" {
#endif

/* No fused multiply-add: every operation rounds as the Python oracle's does. dfwb's builds pass -ffp-contract=off;
   this asks the same of clang and MSVC building the sources with their own defaults (an importer's, e.g. fmpy's
   cmake build). GCC ignores the pragma: it needs -ffp-contract=off (CFLAGS) where the target has FMA (aarch64;
   x86_64 has none without -mfma). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif

#if defined(_WIN32)
#define DFWB_API /* in a DLL only the FMI functions are exported (dllexport in the FMU wrapper) */
#elif defined(__GNUC__) || defined(__clang__)
#define DFWB_API __attribute__((visibility("default")))
#else
#define DFWB_API
#endif

/* The version of this API (dfwb_core_abi_version()); a binding checks it. */
#define DFWB_CORE_ABI 11

/* Status codes. */
#define DFWB_OK 0
#define DFWB_E_VALUE 1    /* a parameter, input or step out of range (Python: PlantError) */
#define DFWB_E_LIMIT 2    /* a loop bound reached: an event search, the events per period, a search
                             chunk, a crossing the phase cannot resolve (Python: PlantError) */
#define DFWB_E_MATH 3     /* a power or an absolute value overflowed (Python: OverflowError) */
#define DFWB_E_MEMORY 4   /* malloc failed (Python: MemoryError) */
#define DFWB_E_ARGUMENT 5 /* a NULL pointer where an object is needed, a buffer too small */
#define DFWB_E_STATE 6    /* bytes that are not a valid state of this plant (Python: StateRefused) */
#define DFWB_E_DIVERGED 7 /* a loop's state grew beyond DFWB_HY_MAX_STATE (Python: Diverged) */

/* Plant kinds (the header of a state): DFWB_PLANT_FRICTION, ... (dfwb_plants.h). The header kind of a closed
 * loop's state (dfwb_loop_to_bytes) is DFWB_STATE_LOOP + the plant kind. */
#define DFWB_STATE_LOOP 256

/* Event kinds of the log: the EventKind of fmus/contract.py (its str in comments). */
#define DFWB_EVENT_BREAK_UP 1     /* "break+" */
#define DFWB_EVENT_BREAK_DOWN 2   /* "break-" */
#define DFWB_EVENT_RELEASE 3      /* "release" */
#define DFWB_EVENT_EDGE 4         /* "edge" */
#define DFWB_EVENT_BAND 5         /* "band" */
#define DFWB_EVENT_WALL_LOWER 6   /* "gap 0" */
#define DFWB_EVENT_WALL_UPPER 7   /* "gap h" */
#define DFWB_EVENT_APEX 8         /* "apex" (never counted nor logged) */
#define DFWB_EVENT_ENGAGE_UP 9    /* "engage+" */
#define DFWB_EVENT_ENGAGE_DOWN 10 /* "engage-" */
#define DFWB_EVENT_REVERSE 11     /* "reverse" */
#define DFWB_EVENT_COULOMB 12     /* "coulomb" (Python's loop alone: the feedforward of the controller's sign) */
#define DFWB_EVENT_DEADBAND 13    /* "deadband" */

#define DFWB_HARMONICS_MAX 10

/* An instance of any plant (its kind: dfwb_plant_kind). */
typedef struct dfwb_plant dfwb_plant;

/* DFWB_CORE_ABI of the compiled library. */
DFWB_API int dfwb_core_abi_version(void);

/* A plant kind's shape: *nparams the length of dfwb_plant_new's array (DFWB_*_PARAMS of dfwb_plants.h),
 * *noutputs of dfwb_plant_output's, *ncounters the counters of dfwb_plant_counter. DFWB_E_ARGUMENT for a
 * kind the core does not know (the arguments untouched); NULL pointers are skipped. */
DFWB_API int dfwb_plant_shape(int kind, size_t *nparams, size_t *noutputs, size_t *ncounters);

/* A new solver of plant kind (DFWB_PLANT_*) at t = 0 from params[nparams], in the order of dfwb_plants.h.
 * On success *out is the instance (free it with dfwb_plant_free); on refusal *out is NULL. */
DFWB_API int dfwb_plant_new(int kind, const double *params, size_t nparams, dfwb_plant **out, char *err,
                            size_t errlen);

/* The instance's plant kind (DFWB_PLANT_*; 0 for NULL). */
DFWB_API int dfwb_plant_kind(const dfwb_plant *p);

/* Set the input force f (finite), held until the next call. */
DFWB_API int dfwb_plant_set_input(dfwb_plant *p, double f, char *err, size_t errlen);

/* Integrate exactly from the current time to t_end (>= the current time, phase within 1e10 rad),
 * firing every event on the way; then the current time is t_end. */
DFWB_API int dfwb_plant_advance(dfwb_plant *p, double t_end, char *err, size_t errlen);

/* out[noutputs] at the current time: friction {x, v, Ff, mode} (mode 0 stick or inside the band, +1/-1
 * sliding); backlash {x1, v1, x2, v2, gap}; static backlash {x, v, y}. */
DFWB_API void dfwb_plant_output(const dfwb_plant *p, double *out);

/* The running integrals I_k(t) = int_0^t y(s) exp(-i k omega s) ds of the output y (friction x, backlash x1,
 * static backlash y), k = 0..harmonics, into re[0..harmonics] and im[0..harmonics] (at most 11 each). */
DFWB_API int dfwb_plant_integrals(const dfwb_plant *p, double *re, double *im, char *err, size_t errlen);
/* A bound on the error of every integral (the unit of the signal times s): 0 for a plant of closed forms, the
 * integrated pieces' bound otherwise (PiecewisePlant.integrals_error); NaN for NULL. */
DFWB_API double dfwb_plant_integrals_error(const dfwb_plant *p);

/* The current time (s), the events counted so far, the number of harmonics (0..10). */
DFWB_API double dfwb_plant_time(const dfwb_plant *p);
DFWB_API long long dfwb_plant_events(const dfwb_plant *p);
DFWB_API int dfwb_plant_harmonics(const dfwb_plant *p);
/* The drive's period 2 pi / omega (s) and out[4] = {f, F, omega, phi} of u = f + F cos(omega t + phi)
 * (F >= 0: a negative amplitude is stored as a phase shift of pi, as the Python Drive does). */
DFWB_API double dfwb_plant_period(const dfwb_plant *p);
DFWB_API void dfwb_plant_drive(const dfwb_plant *p, double out[4]);

/* The plant's i-th counter (the FMU's integer outputs beyond events): backlash 0 contact (0 free, 1 at
 * gap 0, 2 at gap h), 1 impacts so far; static backlash 0 engaged (0 free, +1/-1 at the upper/lower edge of
 * the play); friction none. -1 for NULL or an i out of range. */
DFWB_API long long dfwb_plant_counter(const dfwb_plant *p, size_t i);

/* 1 when a and b are plants of one kind with bit-identical fixed parameters - the plant's constants and
 * what is derived from them (friction M, B, Fc, Fs, Dv, Fc + B Dv; backlash M1, M2, h, eps, M1 + M2,
 * M1 / (M1 + M2), M2 / (M1 + M2), 1e-12 h; static backlash M, k, h), the drive's F, omega, phi, the period,
 * the harmonics - compared as bits (-0.0 != 0.0); 0 otherwise or when either is NULL. */
DFWB_API int dfwb_plant_same_parameters(const dfwb_plant *a, const dfwb_plant *b);

/* An independent exact copy (for an FMU state; its event log copied too), or NULL when out of memory. */
DFWB_API dfwb_plant *dfwb_plant_copy(const dfwb_plant *p);

/* Free an instance (NULL is ignored). */
DFWB_API void dfwb_plant_free(dfwb_plant *p);

/* The event log: capacity > 0 enables it (room for that many entries, grown on demand), 0 disables it
 * and drops its entries. read moves up to max entries, oldest first, into t[] and kind[] (DFWB_EVENT_*)
 * and returns how many; with t or kind NULL or max 0 it returns the number pending. dropped: events not
 * recorded since the log was enabled (it was full, or out of memory). */
DFWB_API void dfwb_plant_log(dfwb_plant *p, size_t capacity);
DFWB_API size_t dfwb_plant_log_read(dfwb_plant *p, double *t, int *kind, size_t max);
DFWB_API unsigned long long dfwb_plant_log_dropped(const dfwb_plant *p);

/* The bytes of a state of plant kind (every state of a kind has the same size); 0 for an unknown kind. */
DFWB_API size_t dfwb_plant_state_size(int kind);
/* The state as bytes: *size = the bytes it takes; written into buf when buf is not NULL (a buffer
 * smaller than *size: DFWB_E_ARGUMENT). */
DFWB_API int dfwb_plant_to_bytes(const dfwb_plant *p, unsigned char *buf, size_t buflen, size_t *size, char *err,
                                 size_t errlen);
/* A new instance of plant kind from bytes of dfwb_plant_to_bytes (DFWB_E_STATE when they are not a valid
 * state of that kind). */
DFWB_API int dfwb_plant_from_bytes(int kind, const unsigned char *buf, size_t len, dfwb_plant **out, char *err,
                                   size_t errlen);

/* -- the exact closed loops (each plant's LOOP, a FeedbackLoop of fmus/loops.py) ------ */
#define DFWB_LOOP_MAX_ORDER 8
#define DFWB_LOOP_MAX_STATE 12               /* 4 plant coordinates + 8 controller states */
/* DFWB_LOOP_*_PARAMS: dfwb_plants.h */

/* Mode keys (dfwb_loop_mode): the Python key tuples in comments. */
#define DFWB_LOOP_STICK 0          /* friction ("stick", 0) */
#define DFWB_LOOP_SLIDE_UP 1       /* friction ("slide", 1) */
#define DFWB_LOOP_SLIDE_DOWN 2     /* friction ("slide", -1) */
#define DFWB_LOOP_FREE 0           /* backlash, static backlash ("free", 0) */
#define DFWB_LOOP_CONTACT_LOWER 1  /* backlash ("contact", -1): held at gap 0 */
#define DFWB_LOOP_CONTACT_UPPER 2  /* backlash ("contact", 1): held at gap h */
#define DFWB_LOOP_ENGAGED_UP 1     /* static backlash ("engaged", 1) */
#define DFWB_LOOP_ENGAGED_DOWN 2   /* static backlash ("engaged", -1) */

typedef struct dfwb_loop dfwb_loop;

/* A new loop at t = 0 (the Python constructors: FrictionLoop(b, a, M, B, Fc, Fs, Dv, x0, v0, z0, state,
 * section), ...). plant: DFWB_PLANT_*; params[nparams]: the plant's parameters in the order of
 * dfwb_plants.h (DFWB_LOOP_*_PARAMS of them; Python's gap0=None is 0.5 * h); b[nb] = {b0..bn},
 * a[na] = {a1..an}; z0[nz0] the controller's initial state (NULL: zeros); state[nstate] the whole loop
 * state (NULL: from the parameters and z0; given, it supersedes them); section (NULL: none) watches the
 * output y rising through *section (dfwb_loop_crossings_read). Checked in Python's order and refused
 * with its texts (DFWB_E_VALUE): the plant's parameters, the order n = na in 1..8, nb = n + 1, a1..an,
 * b0..bn, the state's length, coordinates and range (gap in [0, h], |x - y/k| <= h/2 (1 + 1e-9)), z0's
 * length and values, the section. compensation (NULL: none) = {coulomb 0/1, F_hat, reset 0/1, d, a, w_d, h_hat}:
 * the compensators of fmus/compensation.py the core runs (Coulomb(F_hat) of the velocity, Reset(), Deadband(d),
 * Dither(a, w_d), a = 0 none: its oscillator is two more coordinates of the solver's state, never of the state the
 * API gives or takes; BacklashInverse(h_hat), 0 none: its correction one more, after them; the feedforward of the
 * controller's sign runs in Python alone), checked in Python's order too. */
DFWB_API int dfwb_loop_new(int plant, const double *params, size_t nparams, const double *b, size_t nb,
                           const double *a, size_t na, const double *z0, size_t nz0, const double *state,
                           size_t nstate, const double *section, const double *compensation, dfwb_loop **out,
                           char *err, size_t errlen);
/* The integrator deadband's side (FeedbackLoop.band): -1 below -d, 0 within, +1 above d (1 without one). */
DFWB_API int dfwb_loop_band(const dfwb_loop *p);
/* The loop's compensators as dfwb_loop_new took them: {coulomb 0/1, F_hat, reset 0/1, d, a, w_d, h_hat} (w_d 0
 * where a = 0). */
DFWB_API void dfwb_loop_compensation(const dfwb_loop *p, double out[7]);

/* HybridSolver.advance: integrate exactly to t_end (finite, >= the current time, at most 1e12 chunks of the
 * fastest mode built so far), firing every event on the way. What ends the advance early (then the current
 * time is that instant): stop_section, the next upward crossing of the section; stop_events (NULL: none, else
 * one mask per mode key, 9 of them), the first event of kind (DFWB_EVENT_*) fired from mode key where bit
 * kind of stop_events[key] is set, the state then the one the event left
 * (dfwb_loop_stopped tells which kind stopped it, 0 none). budget_left: NULL for none, else the chunks the
 * study may still integrate (a Budget shared by several loops: decremented per chunk, below 0 refused naming
 * budget_total; written back on refusal too). Events: at most 10000 per chunk of the fastest mode spanned. */
DFWB_API int dfwb_loop_advance(dfwb_loop *p, double t_end, int stop_section, const unsigned int *stop_events,
                               long long *budget_left,
                               long long budget_total, char *err, size_t errlen);
DFWB_API int dfwb_loop_stopped(const dfwb_loop *p); /* the event kind the last advance stopped at, 0: none */
/* dfwb_loop_advance to each of times[0..n-1] (non-decreasing) in turn, the state there into states[i * size ..]
 * (the loop's state size), the mode key into keys[i] and the force on the plant (FeedbackLoop.applied: the
 * controller's on the corrected output, the velocity's feedforward and the dither's) into forces[i] (keys, forces NULL: not written): many
 * samples of one run in one call. Refused as advance refuses (then the samples before the refused time are
 * written). */
DFWB_API int dfwb_loop_sample(dfwb_loop *p, const double *times, size_t n, double *states, int *keys,
                              double *forces, long long *budget_left, long long budget_total, char *err,
                              size_t errlen);

DFWB_API double dfwb_loop_time(const dfwb_loop *p);
DFWB_API long long dfwb_loop_events(const dfwb_loop *p);
DFWB_API int dfwb_loop_plant(const dfwb_loop *p);  /* DFWB_PLANT_* */
DFWB_API int dfwb_loop_order(const dfwb_loop *p);  /* n */
DFWB_API int dfwb_loop_size(const dfwb_loop *p);   /* the state's size: plant coordinates + n */
/* The current mode key (DFWB_LOOP_STICK ...). */
DFWB_API int dfwb_loop_mode(const dfwb_loop *p);
/* The plant's counter: sticks (friction), impacts (backlash), engagements (static backlash). */
DFWB_API long long dfwb_loop_counter(const dfwb_loop *p);
/* X[size] = the loop state at the current time; the output y; the force f = -G(s) y = D y + C z at a given
 * state X[size] (FeedbackLoop.force). */
DFWB_API void dfwb_loop_state(const dfwb_loop *p, double *X);
DFWB_API double dfwb_loop_output(const dfwb_loop *p);
DFWB_API double dfwb_loop_force(const dfwb_loop *p, const double *X);
/* out[9]: the constants its plant's LOOP.CONSTANTS names, in order (friction {M, B, Fc, Fs}, backlash
 * {M1, M2, h, eps, r2 = M2/(M1+M2), tol_h = 1e-12 h}, ...; the rest zeros). */
DFWB_API void dfwb_loop_parameters(const dfwb_loop *p, double out[9]);
/* The controller of -G(s): Ac[n*n] (row-major), Bc[n], C[n] and *D (C and D negated, as FeedbackLoop's);
 * NULL pointers are skipped. */
DFWB_API void dfwb_loop_controller(const dfwb_loop *p, double *Ac, double *Bc, double *C, double *D);

/* The section's upward crossings not read yet (t, X[size]), oldest first: up to max moved into t[max] and
 * X[max * size]; with t or X NULL or max 0 the number pending. Always recorded (as Python's crossings),
 * held until read (grown on demand; when out of memory, counted in dfwb_loop_crossings_dropped). */
DFWB_API size_t dfwb_loop_crossings_read(dfwb_loop *p, double *t, double *X, size_t max);
DFWB_API unsigned long long dfwb_loop_crossings_dropped(const dfwb_loop *p);

/* Modes are built when first needed (bit s of dfwb_loop_modes_built: slot s is built; slot s is mode key s % 9
 * at the deadband's side s / 9: 0 above d (or without a deadband), 1 within, 2 below -d). The solvers of one
 * Python study share their modes, and the fastest built mode bounds a step (t_end and events): a binding
 * sharing them builds those the others have with dfwb_loop_build_modes. mode_info: 1 and the mode's chunk
 * length h and Taylor terms when slot key is built, else 0. */
DFWB_API int dfwb_loop_modes_built(const dfwb_loop *p);
DFWB_API int dfwb_loop_build_modes(dfwb_loop *p, int mask, char *err, size_t errlen);
DFWB_API int dfwb_loop_mode_info(const dfwb_loop *p, int key, double *h, int *terms);

/* An independent exact copy (pending crossings and the event log copied), NULL when out of memory; free. */
DFWB_API dfwb_loop *dfwb_loop_copy(const dfwb_loop *p);
DFWB_API void dfwb_loop_free(dfwb_loop *p);
/* The section: 1 and *level when the loop watches one, else 0. */
DFWB_API int dfwb_loop_section(const dfwb_loop *p, double *level);

/* 1 when a and b are loops of one plant with bit-identical fixed parameters: the plant's constants, the
 * controller's coefficients b and a, the section (none, or its level); 0 otherwise or when either is NULL. */
DFWB_API int dfwb_loop_same_parameters(const dfwb_loop *a, const dfwb_loop *b);

/* The loop's state as bytes (as dfwb_plant_to_bytes; header kind DFWB_STATE_LOOP + the plant kind, one size
 * for every loop of a plant): its parameters and controller coefficients, the section, the time, the counts, the
 * current mode, the modes built, the chunk (its start, its state, the search flags, a pending event).
 * Not in it: the section's crossings not read yet and the event log. from_bytes(plant, ...) makes a loop of
 * that plant from such bytes, checking everything it reads (the parameters as dfwb_loop_new checks them,
 * the modes rebuilt from them, every field's range and the chunk against its mode: 0 <= start <= t <
 * start + h, a pending event within the chunk and one of its mode's); DFWB_E_STATE otherwise. A step from
 * crafted bytes that pass is bounded as every step is. */
DFWB_API int dfwb_loop_to_bytes(const dfwb_loop *p, unsigned char *buf, size_t buflen, size_t *size, char *err,
                                size_t errlen);
DFWB_API int dfwb_loop_from_bytes(int plant, const unsigned char *buf, size_t len, dfwb_loop **out, char *err,
                                  size_t errlen);

/* The event log of the loop's events (not the section's crossings), as dfwb_plant_log. */
DFWB_API void dfwb_loop_log(dfwb_loop *p, size_t capacity);
DFWB_API size_t dfwb_loop_log_read(dfwb_loop *p, double *t, int *kind, size_t max);
DFWB_API unsigned long long dfwb_loop_log_dropped(const dfwb_loop *p);

#ifdef __cplusplus
}
#endif

#endif /* DFWB_CORE_H */
