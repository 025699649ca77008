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
 *   an importer restores a copy (dfwb_*_copy, dfwb_*_from_bytes) or starts anew.
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
 * Parameters of dfwb_friction_new (in this order; the defaults of the Python
 * FrictionMass are M=1, B=0.5, Fc=5, Fs=7, Dv=0, F=0, omega=1, phi=0,
 * x0=0, v0=0, f=0, harmonics=10):
 *   M > 0 (kg), B >= 0 (N.s/m), Fc >= 0 (N), Fs >= Fc (N), Dv >= 0 (m/s),
 *   F finite (N), omega > 0 (rad/s), |phi| <= 1e10 (rad), x0, v0, f finite,
 *   harmonics an integer in 0..10 (passed as a double).
 * They are checked in that order of the Python constructor (M, B, Fc, Fs,
 * Dv, x0, v0, F, omega, phi, f, harmonics): the first refused one is named.
 *
 * Parameters of dfwb_backlash_new (Python TwoMassBacklash: M1=1, M2=1, h=0.1, eps=0.5, F=0, omega=1,
 * phi=0, x1_0=0, v1_0=0, v2_0=0, gap0=None, f=0, harmonics=10):
 *   {M1, M2, h, eps, F, omega, phi, x1_0, v1_0, v2_0, gap0, f, harmonics}: M1, M2 > 0 (kg),
 *   h >= 1e-290 (m), eps in [0, 1], gap0 in [0, h] (Python's gap0=None is h/2: pass 0.5 * h),
 *   the rest as above; checked in the order M1, M2, h, eps, gap0, x1_0, v1_0, v2_0, F, omega, phi, f,
 *   harmonics.
 * Parameters of dfwb_static_backlash_new (Python StaticBacklash: M=2, k=1, h=0.1, F=0, omega=1, phi=0,
 * x0=0, v0=0, f=0, harmonics=10):
 *   {M, k, h, F, omega, phi, x0, v0, f, harmonics}: M, k, h > 0; checked in the order M, k, h, x0, v0,
 *   F, omega, phi, f, harmonics.
 */
#ifndef DFWB_CORE_H
#define DFWB_CORE_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__) || defined(__clang__)
#define DFWB_API __attribute__((visibility("default")))
#else
#define DFWB_API
#endif

/* The version of this API (dfwb_core_abi_version()); a binding checks it. */
#define DFWB_CORE_ABI 3

/* Status codes. */
#define DFWB_OK 0
#define DFWB_E_VALUE 1    /* a parameter, input or step out of range (Python: PlantError) */
#define DFWB_E_LIMIT 2    /* a loop bound reached: an event search, the events per period, a search
                             chunk, a crossing the phase cannot resolve (Python: PlantError) */
#define DFWB_E_MATH 3     /* a power or an absolute value overflowed (Python: OverflowError) */
#define DFWB_E_MEMORY 4   /* malloc failed (Python: MemoryError) */
#define DFWB_E_ARGUMENT 5 /* a NULL pointer where an object is needed, a buffer too small */
#define DFWB_E_STATE 6    /* bytes that are not a valid state of this plant (Python: StateRefused) */

/* Plant kinds (the header of a state). */
#define DFWB_PLANT_FRICTION 1
#define DFWB_PLANT_BACKLASH 2
#define DFWB_PLANT_STATIC_BACKLASH 3

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

/* Modes reported by dfwb_friction_output (out[3]): 0 stick or inside the band, +1/-1 sliding. */

#define DFWB_HARMONICS_MAX 10
#define DFWB_FRICTION_PARAMS 12
#define DFWB_BACKLASH_PARAMS 13
#define DFWB_STATIC_BACKLASH_PARAMS 10

typedef struct dfwb_friction dfwb_friction;
typedef struct dfwb_backlash dfwb_backlash;
typedef struct dfwb_static_backlash dfwb_static_backlash;

/* DFWB_CORE_ABI of the compiled library. */
DFWB_API int dfwb_core_abi_version(void);

/* A new solver at t = 0 from params[12] = {M, B, Fc, Fs, Dv, F, omega, phi, x0, v0, f, harmonics}.
 * On success *out is the instance (free it with dfwb_friction_free); on refusal *out is NULL. */
DFWB_API int dfwb_friction_new(const double params[DFWB_FRICTION_PARAMS], dfwb_friction **out,
                               char *err, size_t errlen);

/* Set the input force f (finite), held until the next call. */
DFWB_API int dfwb_friction_set_input(dfwb_friction *p, double f, char *err, size_t errlen);

/* Integrate exactly from the current time to t_end (>= the current time, phase within 1e10 rad),
 * firing every event on the way; then the current time is t_end. */
DFWB_API int dfwb_friction_advance(dfwb_friction *p, double t_end, char *err, size_t errlen);

/* out[4] = {x, v, Ff, mode} at the current time. */
DFWB_API void dfwb_friction_output(const dfwb_friction *p, double out[4]);

/* The running integrals I_k(t) = int_0^t x(s) exp(-i k omega s) ds, k = 0..harmonics, into
 * re[0..harmonics] and im[0..harmonics] (arrays of harmonics + 1 doubles; at most 11). */
DFWB_API int dfwb_friction_integrals(const dfwb_friction *p, double *re, double *im, char *err, size_t errlen);

/* The current time (s), the events counted so far, the number of harmonics (0..10). */
DFWB_API double dfwb_friction_time(const dfwb_friction *p);
DFWB_API long long dfwb_friction_events(const dfwb_friction *p);
DFWB_API int dfwb_friction_harmonics(const dfwb_friction *p);
/* The drive's period 2 pi / omega (s) and out[4] = {f, F, omega, phi} of u = f + F cos(omega t + phi)
 * (F >= 0: a negative amplitude is stored as a phase shift of pi, as the Python Drive does). */
DFWB_API double dfwb_friction_period(const dfwb_friction *p);
DFWB_API void dfwb_friction_drive(const dfwb_friction *p, double out[4]);

/* 1 when a and b have bit-identical fixed parameters (M, B, Fc, Fs, Dv and the friction just outside the
 * band Fc + B Dv; the drive's F, omega, phi; the period; the harmonics), compared as bits (-0.0 != 0.0);
 * 0 otherwise or when either is NULL. The input f, the time and the motion are not compared. */
DFWB_API int dfwb_friction_same_parameters(const dfwb_friction *a, const dfwb_friction *b);

/* An independent exact copy (for an FMU state; its event log copied too), or NULL when out of memory. */
DFWB_API dfwb_friction *dfwb_friction_copy(const dfwb_friction *p);

/* Free an instance (NULL is ignored). */
DFWB_API void dfwb_friction_free(dfwb_friction *p);

/* The event log: capacity > 0 enables it (room for that many entries, grown on demand), 0 disables it
 * and drops its entries. read moves up to max entries, oldest first, into t[] and kind[] (DFWB_EVENT_*)
 * and returns how many; with t or kind NULL or max 0 it returns the number pending. dropped: events not
 * recorded since the log was enabled (it was full, or out of memory). */
DFWB_API void dfwb_friction_log(dfwb_friction *p, size_t capacity);
DFWB_API size_t dfwb_friction_log_read(dfwb_friction *p, double *t, int *kind, size_t max);
DFWB_API unsigned long long dfwb_friction_log_dropped(const dfwb_friction *p);

/* The state as bytes: *size = the bytes it takes; written into buf when buf is not NULL (a buffer
 * smaller than *size: DFWB_E_ARGUMENT). With buf NULL it is a size query (p may be NULL): every state
 * of a plant kind has the same size. */
DFWB_API int dfwb_friction_to_bytes(const dfwb_friction *p, unsigned char *buf, size_t buflen, size_t *size,
                                    char *err, size_t errlen);
/* A new instance from bytes of dfwb_friction_to_bytes (DFWB_E_STATE when they are not a valid state). */
DFWB_API int dfwb_friction_from_bytes(const unsigned char *buf, size_t len, dfwb_friction **out, char *err,
                                      size_t errlen);

/* -- the two-mass backlash (TwoMassBacklash) ------------------------------------------------ */
/* params[13] = {M1, M2, h, eps, F, omega, phi, x1_0, v1_0, v2_0, gap0, f, harmonics}. */
DFWB_API int dfwb_backlash_new(const double params[DFWB_BACKLASH_PARAMS], dfwb_backlash **out, char *err,
                               size_t errlen);
DFWB_API int dfwb_backlash_set_input(dfwb_backlash *p, double f, char *err, size_t errlen);
DFWB_API int dfwb_backlash_advance(dfwb_backlash *p, double t_end, char *err, size_t errlen);
/* out[5] = {x1, v1, x2, v2, gap} at the current time. */
DFWB_API void dfwb_backlash_output(const dfwb_backlash *p, double out[5]);
/* Running integrals of x1 (as dfwb_friction_integrals). */
DFWB_API int dfwb_backlash_integrals(const dfwb_backlash *p, double *re, double *im, char *err, size_t errlen);
DFWB_API double dfwb_backlash_time(const dfwb_backlash *p);
DFWB_API long long dfwb_backlash_events(const dfwb_backlash *p);
DFWB_API int dfwb_backlash_harmonics(const dfwb_backlash *p);
DFWB_API double dfwb_backlash_period(const dfwb_backlash *p);
DFWB_API void dfwb_backlash_drive(const dfwb_backlash *p, double out[4]);
/* The FMU's counters: contact 0 free, 1 at gap 0, 2 at gap h; impacts so far. */
DFWB_API int dfwb_backlash_contact(const dfwb_backlash *p);
DFWB_API long long dfwb_backlash_impacts(const dfwb_backlash *p);
/* As dfwb_friction_same_parameters: M1, M2, h, eps, the derived M1 + M2, M1 / (M1 + M2), M2 / (M1 + M2),
 * 1e-12 h; the drive's F, omega, phi; the period; the harmonics. */
DFWB_API int dfwb_backlash_same_parameters(const dfwb_backlash *a, const dfwb_backlash *b);
DFWB_API dfwb_backlash *dfwb_backlash_copy(const dfwb_backlash *p);
DFWB_API void dfwb_backlash_free(dfwb_backlash *p);
DFWB_API void dfwb_backlash_log(dfwb_backlash *p, size_t capacity);
DFWB_API size_t dfwb_backlash_log_read(dfwb_backlash *p, double *t, int *kind, size_t max);
DFWB_API unsigned long long dfwb_backlash_log_dropped(const dfwb_backlash *p);
DFWB_API int dfwb_backlash_to_bytes(const dfwb_backlash *p, unsigned char *buf, size_t buflen, size_t *size,
                                    char *err, size_t errlen);
DFWB_API int dfwb_backlash_from_bytes(const unsigned char *buf, size_t len, dfwb_backlash **out, char *err,
                                      size_t errlen);

/* -- the static backlash (StaticBacklash) ------------------------------------------------------ */
/* params[10] = {M, k, h, F, omega, phi, x0, v0, f, harmonics}. */
DFWB_API int dfwb_static_backlash_new(const double params[DFWB_STATIC_BACKLASH_PARAMS], dfwb_static_backlash **out,
                                      char *err, size_t errlen);
DFWB_API int dfwb_static_backlash_set_input(dfwb_static_backlash *p, double f, char *err, size_t errlen);
DFWB_API int dfwb_static_backlash_advance(dfwb_static_backlash *p, double t_end, char *err, size_t errlen);
/* out[3] = {x, v, y} at the current time. */
DFWB_API void dfwb_static_backlash_output(const dfwb_static_backlash *p, double out[3]);
/* Running integrals of y (as dfwb_friction_integrals). */
DFWB_API int dfwb_static_backlash_integrals(const dfwb_static_backlash *p, double *re, double *im, char *err,
                                            size_t errlen);
DFWB_API double dfwb_static_backlash_time(const dfwb_static_backlash *p);
DFWB_API long long dfwb_static_backlash_events(const dfwb_static_backlash *p);
DFWB_API int dfwb_static_backlash_harmonics(const dfwb_static_backlash *p);
DFWB_API double dfwb_static_backlash_period(const dfwb_static_backlash *p);
DFWB_API void dfwb_static_backlash_drive(const dfwb_static_backlash *p, double out[4]);
/* The FMU's counter: 0 free, +1/-1 engaged at the upper/lower edge of the play. */
DFWB_API int dfwb_static_backlash_engaged(const dfwb_static_backlash *p);
/* As dfwb_friction_same_parameters: M, k, h; the drive's F, omega, phi; the period; the harmonics. */
DFWB_API int dfwb_static_backlash_same_parameters(const dfwb_static_backlash *a, const dfwb_static_backlash *b);
DFWB_API dfwb_static_backlash *dfwb_static_backlash_copy(const dfwb_static_backlash *p);
DFWB_API void dfwb_static_backlash_free(dfwb_static_backlash *p);
DFWB_API void dfwb_static_backlash_log(dfwb_static_backlash *p, size_t capacity);
DFWB_API size_t dfwb_static_backlash_log_read(dfwb_static_backlash *p, double *t, int *kind, size_t max);
DFWB_API unsigned long long dfwb_static_backlash_log_dropped(const dfwb_static_backlash *p);
DFWB_API int dfwb_static_backlash_to_bytes(const dfwb_static_backlash *p, unsigned char *buf, size_t buflen,
                                           size_t *size, char *err, size_t errlen);
DFWB_API int dfwb_static_backlash_from_bytes(const unsigned char *buf, size_t len, dfwb_static_backlash **out,
                                             char *err, size_t errlen);

#ifdef __cplusplus
}
#endif

#endif /* DFWB_CORE_H */
