/* dfwb_core.h - the exact friction-mass solver of dfwb in C99: the public API.
 *
 * A faithful port of the pure-Python solver (fmus/exact.py, fmus/piecewise.py,
 * fmus/friction.py), which stays the oracle: the same closed forms, the same
 * event searches, the same bounds on every loop, the same operation order
 * (complex arithmetic mirrors CPython's, libm is called where Python calls
 * it), so that both agree to rounding - in practice bit for bit.
 *
 *     M x'' + Ff = u(t),   u = f + F cos(omega t + phi)
 *
 * Sliding (|v| > Dv): Ff = Fc sgn(v) + B v; Dv = 0 sticks at v = 0 while
 * |u| <= Fs, Dv > 0 is Karnopp's band (see fmus/friction.py).
 *
 * Conventions
 * -----------
 * - Every function that can refuse returns an int status (DFWB_OK = 0) and,
 *   when err is not NULL and errlen > 0, writes a one-line, NUL-terminated
 *   message into err (truncated to errlen): the text of the Python
 *   PlantError (floats written as Python's repr writes them).
 * - No global mutable state: one dfwb_friction per instance, re-entrant;
 *   instances may be used from different threads, one thread at a time each.
 * - No exit, abort or output. Memory: malloc/realloc/free only.
 * - After a refusal of set_input or advance the instance is valid but its
 *   state is unspecified (as in Python, where the step stops half way):
 *   an importer restores a copy (dfwb_friction_copy) or starts anew.
 *
 * Parameters (dfwb_friction_new, in this order; the defaults of the Python
 * FrictionMass are M=1, B=0.5, Fc=5, Fs=7, Dv=0, F=0, omega=1, phi=0,
 * x0=0, v0=0, f=0, harmonics=10):
 *   M > 0 (kg), B >= 0 (N.s/m), Fc >= 0 (N), Fs >= Fc (N), Dv >= 0 (m/s),
 *   F finite (N), omega > 0 (rad/s), |phi| <= 1e10 (rad), x0, v0, f finite,
 *   harmonics an integer in 0..10 (passed as a double).
 * They are checked in that order of the Python constructor (M, B, Fc, Fs,
 * Dv, x0, v0, F, omega, phi, f, harmonics): the first refused one is named.
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
#define DFWB_CORE_ABI 1

/* Status codes. */
#define DFWB_OK 0
#define DFWB_E_VALUE 1    /* a parameter, input or step out of range (Python: PlantError) */
#define DFWB_E_LIMIT 2    /* a loop bound reached: an event search, the events per period, a search
                             chunk, a crossing the phase cannot resolve (Python: PlantError) */
#define DFWB_E_MATH 3     /* a power or an absolute value overflowed (Python: OverflowError) */
#define DFWB_E_MEMORY 4   /* malloc failed (Python: MemoryError) */
#define DFWB_E_ARGUMENT 5 /* a NULL pointer where an object is needed */

/* Modes reported by dfwb_friction_output (out[3]): 0 stick or inside the band, +1/-1 sliding. */

#define DFWB_HARMONICS_MAX 10
#define DFWB_FRICTION_PARAMS 12

typedef struct dfwb_friction dfwb_friction;

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

/* An independent exact copy (for an FMU state), or NULL when out of memory. */
DFWB_API dfwb_friction *dfwb_friction_copy(const dfwb_friction *p);

/* Free an instance (NULL is ignored). */
DFWB_API void dfwb_friction_free(dfwb_friction *p);

#ifdef __cplusplus
}
#endif

#endif /* DFWB_CORE_H */
