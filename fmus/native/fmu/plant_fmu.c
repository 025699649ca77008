/* plant_fmu.c - one dfwb plant as an FMU instance on the C core, for the FMI 2.0 and 3.0 layers (fmi2_plant.c,
   fmi3_plant.c, plant_fmu.h): no Python anywhere.

   The native twin of the pythonfmu facades of fmus/facade.py (FrictionMass, TwoMassBacklash,
   StaticBacklash): same model name, variables, value references, start values and ranges (the builder,
   build_fmus/native.py, writes them from the facade into dfwb_model.h and modelDescription.xml), the same
   solver (the C port, bit-identical to the Python one) and the same behaviour:

   - Time: the start time t0 (fmi2SetupExperiment, fmi3EnterInitializationMode) is honoured; the excitation F cos(omega t + phi) is in
     absolute time and the Fourier outputs I_k(t) = int_{t0}^{t} y exp(-i k omega s) ds in absolute phase.
   - Errors: a refused call logs one message (status Error, "<Model>: <the facade's text>") and
     returns Error; the instance is then in FMI's Error state, where only the getters,
     fmi2SetFMUstate, fmi2Reset and fmi2FreeInstance make sense (any other call is refused, naming it).
     Refused: a bad parameter (at fmi2ExitInitializationMode, the solver's own message), a parameter set
     after initialisation (its value is kept), an input that is not finite or beyond 1e100, a step at
     the wrong time or of a bad length, fmi2DoStep before initialisation or after fmi2Terminate, a
     valueReference that is not a variable of that type, NULL arrays, an Integer output (a counter) beyond
     32 bits. A step the solver refuses half way keeps the outputs of the last good point (never NaN);
     outputs that overflow at the start leave the start values (0).
   - FMU state: fmi2GetFMUstate copies the instance exactly (the solver included); fmi2SetFMUstate
     restores it (the outputs are the state's own: 0 for a state before initialisation); a state handle
     of another FMU (a tag of the GUID marks this model's) is refused, never read as this model's; a
     serialized state ("DFWBFMUS", a version, the plant kind, the model's GUID, the facade's values, the
     solver's checked bytes of dfwb_plant_to_bytes) is accepted only by this model of the same build, and only
     when every field is valid and the solver's fixed parameters are those its parameter values make
     (dfwb_*_same_parameters) at the state's time.

   (Calls are named as in FMI 2.0, "getFMUstate", "doStep", ...; the FMI 3.0 layer names its getters
   and setters itself.)

   Memory: the instance and FMU states use the FMI layer's allocate/release (FMI 2.0: the host's
   allocateMemory/freeMemory; FMI 3.0: calloc/free); the core mallocs its own. Logging: OK messages only
   while logging is on; warnings and errors always.

   Build (build_fmus/native.py): cc -O2 -std=c99 -ffp-contract=off -fPIC -shared -fvisibility=hidden
   -I<FMI headers> -I<folder of dfwb_model.h> -I<core sources> fmi<N>_plant.c plant_fmu.c <core *.c> -lm; for
   win64, x86_64-w64-mingw32-gcc with -D__USE_MINGW_ANSI_STDIO=1 -static-libgcc instead of -fPIC -fvisibility. */

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "dfwb_core.h"
#include "exact.h"
#include "plant.h"
#include "plant_fmu.h"


/* Roles of a variable in dfwb_model.h. */
enum {
    ROLE_PARAMETER = 1, /* index: the core parameter it sets */
    ROLE_INPUT,         /* the input force f */
    ROLE_OUTPUT,        /* index: into dfwb_plant_output's array */
    ROLE_EVENTS,
    ROLE_COUNTER, /* index: the plant's counter (dfwb_plant_counter) */
    ROLE_COSINE, /* index: k of Ick */
    ROLE_SINE,   /* index: k of Isk */
    ROLE_TIME,   /* the independent variable (FMI 3.0 declares it) */
    ROLE_ERROR   /* I_error: an integrated plant's bound on its Fourier integrals' error */
};

typedef struct {
    const char *name;
    int integer; /* an Integer variable (else Real) */
    int role;
    int index;
    double start;
} model_variable;

#include "dfwb_model.h" /* DFWB_MODEL_NAME, _KIND, _GUID, _VARIABLES[], _NVARS, _INPUT_PARAMETER, ... */

typedef dfwb_plant plant;
#define NPARAMS DFWB_MODEL_PARAMS /* dfwb_model.h: the plant's shape (dfwb_plant_shape) */
#define NOUT DFWB_MODEL_OUTPUTS

#define NVARS (sizeof DFWB_MODEL_VARIABLES / sizeof DFWB_MODEL_VARIABLES[0])
#define NK (DFWB_HARMONICS_MAX + 1)
#define MAX_INPUT 1e100
#define MESSAGE 1200

enum phase { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, ERROR };
static const char *const PHASES[] = {"instantiated", "initialization mode", "stepping", "terminated", "error"};

/* What a state holds besides the solver (the Python facade's values, state.FMUState.values). */
typedef struct {
    int phase;
    double start, time;
    double values[NVARS]; /* parameters and the input (Integer ones as doubles); outputs unused */
} facade;

typedef struct {
    uint64_t tag;  /* state_tag(): a state of another FMU is refused, never read as ours (0 once freed) */
    facade f;
    plant *solver; /* NULL before initialisation */
} fmu_state;

struct plant_fmu {
    plant_host host;
    char *name;
    int logging;
    facade f;
    plant *solver;
    /* derived from the solver: the outputs of the last good point, the Fourier integrals */
    double outputs[NVARS];
    int overflow, frozen;
    int fourier_known;
    double cosine[NK], sine[NK];
    int rotated;
    dfwb_cx rotation[NK];
};
typedef plant_fmu instance;

/* -- messages --------------------------------------------------------------------------- */
static void emit(instance *c, int status, const char *category, const char *text)
{
    if (status < PLANT_WARNING && !c->logging) return;
    c->host.log(&c->host, c->name, status, category, text);
}

/* Refuse the current call: log "<Model>: <message>" with status error, enter the Error state. */
int plant_fmu_refuse(instance *c, const char *fmt, ...)
{
    char text[MESSAGE];
    int n = snprintf(text, sizeof text, "%s: ", DFWB_MODEL_NAME);
    va_list args;
    va_start(args, fmt);
    vsnprintf(text + n, sizeof text - (size_t)n, fmt, args);
    va_end(args);
    emit(c, PLANT_ERROR, "logStatusError", text);
    c->f.phase = ERROR;
    return PLANT_ERROR;
}

#define refuse plant_fmu_refuse

/* repr of a float (and of an Integer variable's value, an int) as Python writes it. */
typedef struct {
    char s[DFWB_REPR_SIZE];
} repr_t;

static repr_t repr(double x)
{
    repr_t r;
    dfwb_repr(x, r.s);
    return r;
}

static repr_t repr_value(const model_variable *v, double x)
{
    repr_t r;
    if (v->integer)
        snprintf(r.s, sizeof r.s, "%lld", (long long)x);
    else
        dfwb_repr(x, r.s);
    return r;
}

/* Refuse unless in one of the phases (mask of 1 << phase): "<call> is not allowed in the <phase> state". */
static int expect(instance *c, const char *call, unsigned phases)
{
    if (phases & (1u << c->f.phase)) return 1;
    refuse(c, "%s is not allowed in the %s state%s", call, PHASES[c->f.phase],
           c->f.phase == ERROR ? " (after an error only getters, setFMUstate, reset and freeInstance)" : "");
    return 0;
}

#define ANY_BUT_ERROR ((1u << INSTANTIATED) | (1u << INITIALIZATION) | (1u << STEPPING) | (1u << TERMINATED))

/* -- the solver ------------------------------------------------------------------------------ */
static const model_variable *variable(size_t vr) { return vr < NVARS ? &DFWB_MODEL_VARIABLES[vr] : NULL; }

static int settable(const model_variable *v) { return v->role == ROLE_PARAMETER || v->role == ROLE_INPUT; }

static double input_value(const facade *f)
{
    size_t i;
    for (i = 0; i < NVARS; i++)
        if (DFWB_MODEL_VARIABLES[i].role == ROLE_INPUT) return f->values[i];
    return 0.0;
}

/* The core's parameters from the facade's values, the phase turned to the start time t0. */
static void core_parameters(const facade *f, double params[NPARAMS])
{
    size_t i;
    memset(params, 0, NPARAMS * sizeof params[0]);
    for (i = 0; i < NVARS; i++) {
        const model_variable *v = &DFWB_MODEL_VARIABLES[i];
        if (v->role == ROLE_PARAMETER) params[v->index] = f->values[i];
    }
    params[DFWB_MODEL_INPUT_PARAMETER] = input_value(f);
    if (f->start != 0.0) /* F cos(omega t + phi) = F cos(omega (t - t0) + phi + omega t0) */
        params[DFWB_MODEL_PHI_PARAMETER] = params[DFWB_MODEL_PHI_PARAMETER] + params[DFWB_MODEL_OMEGA_PARAMETER] * f->start;
#ifdef DFWB_MODEL_HALF_PARAMETER
    /* a parameter whose start value stands for half another (gap0 = -1: h/2, centred whatever h is) */
    if (params[DFWB_MODEL_HALF_PARAMETER] == DFWB_MODEL_HALF_START)
        params[DFWB_MODEL_HALF_PARAMETER] = 0.5 * params[DFWB_MODEL_HALF_OF];
#endif
}

/* The core names an Integer parameter's value as a float ("harmonics = 11.0"): write it as the int it is. */
static void integer_values(const facade *f, char *err)
{
    size_t i, n;
    for (i = 0; i < NVARS; i++) {
        const model_variable *v = &DFWB_MODEL_VARIABLES[i];
        char as_float[DFWB_REPR_SIZE + 64], as_int[DFWB_REPR_SIZE + 64];
        if (!(v->role == ROLE_PARAMETER && v->integer)) continue;
        snprintf(as_float, sizeof as_float, "%s = %s", v->name, repr(f->values[i]).s);
        snprintf(as_int, sizeof as_int, "%s = %s", v->name, repr_value(v, f->values[i]).s);
        n = strlen(as_float);
        if (strncmp(err, as_float, n) == 0 && strlen(as_int) <= n) { /* int32: never longer */
            memmove(err + strlen(as_int), err + n, strlen(err + n) + 1);
            memcpy(err, as_int, strlen(as_int));
        }
    }
}

static int new_solver(const facade *f, plant **out, char *err, size_t errlen)
{
    double params[NPARAMS];
    int rc;
    core_parameters(f, params);
    rc = dfwb_plant_new(DFWB_MODEL_KIND, params, NPARAMS, out, err, errlen);
    if (rc != DFWB_OK && err) integer_values(f, err);
    return rc;
}

/* exp(-i k omega t0), k = 0..harmonics, as cmath.exp(-1j * k * omega * t0) computes it. */
static void set_rotation(instance *c)
{
    int k;
    c->rotated = c->solver != NULL && c->f.start != 0.0;
    if (!c->rotated) return;
    for (k = 0; k <= dfwb_plant_harmonics(c->solver); k++) {
        dfwb_cx z = dfwb_cx_make(-0.0, -1.0);
        z = dfwb_cx_mul(z, dfwb_cx_real((double)k));
        z = dfwb_cx_mul(z, dfwb_cx_real(c->f.values[DFWB_MODEL_OMEGA_VR]));
        z = dfwb_cx_mul(z, dfwb_cx_real(c->f.start));
        c->rotation[k] = isfinite(z.re) && isfinite(z.im) ? dfwb_cx_exp(z) : dfwb_cx_make(NAN, NAN);
    }
}

/* The outputs after a step (PlantFMU._refresh): kept at the last good point once one overflows. */
static void refresh(instance *c)
{
    double state[NOUT], fresh[NVARS];
    size_t i;
    int overflow = 0;
    if (c->frozen) return;
    dfwb_plant_output(c->solver, state);
    for (i = 0; i < NVARS; i++) {
        const model_variable *v = &DFWB_MODEL_VARIABLES[i];
        double value = 0.0;
        switch (v->role) {
        case ROLE_OUTPUT: value = state[v->index]; break;
        case ROLE_EVENTS: value = (double)dfwb_plant_events(c->solver); break;
        case ROLE_COUNTER: value = (double)dfwb_plant_counter(c->solver, (size_t)v->index); break;
        case ROLE_ERROR: value = dfwb_plant_integrals_error(c->solver); break;
        default: continue;
        }
        fresh[i] = value;
        if (!isfinite(value)) overflow = 1;
    }
    c->overflow = overflow;
    if (overflow) return; /* never NaN: the last good point stays (none yet, at the start: the start values) */
    for (i = 0; i < NVARS; i++) {
        int role = DFWB_MODEL_VARIABLES[i].role;
        if (role != ROLE_PARAMETER && role != ROLE_INPUT && role != ROLE_COSINE && role != ROLE_SINE &&
            role != ROLE_TIME)
            c->outputs[i] = fresh[i];
    }
    c->fourier_known = 0;
}

/* The Fourier integrals in absolute phase (Ick = Re I_k, Isk = -Im I_k); 0 on refusal. */
static int fourier(instance *c)
{
    double re[NK], im[NK];
    char err[MESSAGE];
    int k, n;
    if (c->fourier_known || !c->solver) return 1;
    n = dfwb_plant_harmonics(c->solver);
    if (dfwb_plant_integrals(c->solver, re, im, err, sizeof err) != DFWB_OK) {
        refuse(c, "getReal failed: %s", err);
        return 0;
    }
    for (k = 0; k < NK; k++) c->cosine[k] = c->sine[k] = 0.0;
    for (k = 0; k <= n; k++) {
        dfwb_cx value = dfwb_cx_make(re[k], im[k]);
        if (c->rotated) value = dfwb_cx_mul(value, c->rotation[k]);
        if (!(isfinite(value.re) && isfinite(value.im))) {
            refuse(c, "the Fourier integrals at t = %s overflow a float", repr(c->f.time).s);
            return 0;
        }
        c->cosine[k] = value.re;
        c->sine[k] = -value.im;
    }
    c->fourier_known = 1;
    return 1;
}

/* A step failed half way: outputs stay at the last good point, the integrals too if known (else 0). */
static void broken(instance *c)
{
    if (!c->fourier_known) {
        memset(c->cosine, 0, sizeof c->cosine);
        memset(c->sine, 0, sizeof c->sine);
        c->fourier_known = 1;
    }
    c->frozen = 1;
}

static void defaults(instance *c)
{
    size_t i;
    memset(&c->f, 0, sizeof c->f);
    for (i = 0; i < NVARS; i++) c->f.values[i] = DFWB_MODEL_VARIABLES[i].start;
    c->f.phase = INSTANTIATED;
    memset(c->outputs, 0, sizeof c->outputs);
    c->overflow = c->frozen = c->fourier_known = c->rotated = 0;
}

static void *allocate(const instance *c, size_t size) { return c->host.allocate(1, size); }

/* -- instantiation ---------------------------------------------------------------------------- */
const char *plant_fmu_model(void) { return DFWB_MODEL_NAME; }
const char *plant_fmu_token(void) { return DFWB_MODEL_GUID; }

plant_fmu *plant_fmu_new(const char *name, int logging, const plant_host *host)
{
    instance *c = host->allocate(1, sizeof *c);
    size_t n = name ? strlen(name) : 0;
    if (!c) return NULL;
    c->host = *host;
    c->name = host->allocate(n + 1, 1);
    if (!c->name) {
        host->release(c);
        return NULL;
    }
    if (n) memcpy(c->name, name, n);
    c->name[n] = '\0';
    c->logging = logging;
    c->solver = NULL;
    defaults(c);
    return c;
}

void plant_fmu_free(plant_fmu *c)
{
    if (!c) return;
    dfwb_plant_free(c->solver);
    c->host.release(c->name);
    c->host.release(c);
}

const char *plant_fmu_name(const plant_fmu *c) { return c->name; }

void plant_fmu_logging(plant_fmu *c, int on) { c->logging = on; }

int plant_fmu_reset(plant_fmu *c)
{
    dfwb_plant_free(c->solver);
    c->solver = NULL;
    defaults(c);
    return PLANT_OK;
}

double plant_fmu_time(const plant_fmu *c) { return c->f.time; }

/* -- initialisation, steps ----------------------------------------------------------------------- */
int plant_fmu_setup(plant_fmu *c, double startTime)
{
    if (!expect(c, "setupExperiment", 1u << INSTANTIATED)) return PLANT_ERROR;
    if (!isfinite(startTime))
        return refuse(c, "start time %s refused: it must be a finite number", repr(startTime).s);
    c->f.start = c->f.time = startTime;
    return PLANT_OK;
}

int plant_fmu_enter_initialization(plant_fmu *c)
{
    if (!expect(c, "enterInitializationMode", 1u << INSTANTIATED)) return PLANT_ERROR;
    c->f.phase = INITIALIZATION;
    return PLANT_OK;
}

static int input_ok(instance *c, double value)
{
    if (isfinite(value) && fabs(value) <= MAX_INPUT) return 1;
    refuse(c, "at t = %s: f = %s is out of range: the input f must be a finite number of magnitude <= 1e+100",
           repr(c->f.time).s, repr(value).s);
    return 0;
}

int plant_fmu_exit_initialization(plant_fmu *c)
{
    char err[MESSAGE];
    if (!expect(c, "exitInitializationMode", 1u << INITIALIZATION)) return PLANT_ERROR;
    if (!input_ok(c, input_value(&c->f))) return PLANT_ERROR;
    if (new_solver(&c->f, &c->solver, err, sizeof err) != DFWB_OK) return refuse(c, "invalid parameter: %s", err);
    set_rotation(c);
    refresh(c);
    if (c->overflow) {
        dfwb_plant_free(c->solver);
        c->solver = NULL;
        return refuse(c, "invalid parameters: the outputs at the start overflow a float (a force or a mass "
                         "out of scale)");
    }
    c->f.phase = STEPPING;
    return PLANT_OK;
}

int plant_fmu_step(plant_fmu *c, double t, double h)
{
    char err[MESSAGE];
    double now, end;
    if (c->f.phase == TERMINATED) return refuse(c, "doStep at t = %s refused: the FMU is terminated", repr(t).s);
    if (!c->solver || c->f.phase == INSTANTIATED || c->f.phase == INITIALIZATION)
        return refuse(c, "doStep called before initialisation");
    if (!expect(c, "doStep", 1u << STEPPING)) return PLANT_ERROR;
    if (!(isfinite(h) && h > 0.0))
        return refuse(c, "communication step %s at t = %s: it must be > 0 and finite", repr(h).s, repr(t).s);
    now = c->f.time;
    if (!(fabs(t - now) <= 1e-9 * fmax(1.0, fabs(now)))) /* NaN refused too */
        return refuse(c, "doStep at t = %s, but the FMU is at t = %s", repr(t).s, repr(now).s);
    end = fmax(t + h, now);
    if (dfwb_plant_set_input(c->solver, input_value(&c->f), err, sizeof err) != DFWB_OK ||
        dfwb_plant_advance(c->solver, end - c->f.start, err, sizeof err) != DFWB_OK) {
        broken(c);
        return refuse(c, "step from t = %s refused: %s", repr(t).s, err);
    }
    c->f.time = end;
    refresh(c);
    if (c->overflow) {
        broken(c);
        return refuse(c, "step from t = %s to %s refused: the motion overflows a float (outputs are no longer "
                         "finite)", repr(t).s, repr(end).s);
    }
    return PLANT_OK;
}

int plant_fmu_terminate(plant_fmu *c)
{
    if (!expect(c, "terminate", 1u << STEPPING)) return PLANT_ERROR;
    c->f.phase = TERMINATED;
    return PLANT_OK;
}

/* -- variables --------------------------------------------------------------------------------- */
/* The variables of vr[] (each of the kind asked), or 0 after a refusal naming the first that is not. */
static int lookup(instance *c, const char *call, const plant_vr vr[], size_t n, int integer,
                  const void *values)
{
    size_t i;
    if (n > 0 && (!vr || !values)) {
        refuse(c, "%s: a NULL array for %zu valueReferences", call, n);
        return 0;
    }
    for (i = 0; i < n; i++) {
        const model_variable *v = variable(vr[i]);
        if (!v || v->integer != integer) {
            refuse(c, "%s failed: TypeError: Variable with valueReference=%u is not of type %s!", call,
                   (unsigned)vr[i], integer ? c->host.integer_kind : c->host.real_kind);
            return 0;
        }
    }
    return 1;
}

static double value_of(instance *c, size_t vr, int *ok)
{
    const model_variable *v = &DFWB_MODEL_VARIABLES[vr];
    *ok = 1;
    if (settable(v)) return c->f.values[vr];
    if (v->role == ROLE_COSINE || v->role == ROLE_SINE) {
        if (!c->solver && !c->fourier_known) return 0.0;
        if (!fourier(c)) {
            *ok = 0;
            return 0.0;
        }
        return v->role == ROLE_COSINE ? c->cosine[v->index] : c->sine[v->index];
    }
    if (v->role == ROLE_TIME) return c->f.time;
    return c->outputs[vr];
}

int plant_fmu_get_reals(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, double value[])
{
    size_t i;
    int ok = 1;
    if (!lookup(c, call, vr, n, 0, value)) {
        if (value) memset(value, 0, n * sizeof value[0]);
        return PLANT_ERROR;
    }
    for (i = 0; i < n && ok; i++) value[i] = value_of(c, vr[i], &ok);
    if (!ok) {
        memset(value, 0, n * sizeof value[0]);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

int plant_fmu_get_integers(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, int value[])
{
    size_t i;
    int ok;
    if (!lookup(c, call, vr, n, 1, value)) {
        if (value) memset(value, 0, n * sizeof value[0]);
        return PLANT_ERROR;
    }
    for (i = 0; i < n; i++) {
        double x = value_of(c, vr[i], &ok);
        if (!(x >= -2147483648.0 && x <= 2147483647.0)) { /* a counter of a long run or of a crafted state */
            memset(value, 0, n * sizeof value[0]);
            return refuse(c, "%s: %s = %.0f does not fit a 32-bit Integer", call, DFWB_MODEL_VARIABLES[vr[i]].name,
                          x);
        }
        value[i] = (int)x;
    }
    return PLANT_OK;
}

/* SolverFMU._set_values: everything checked first, then all set (a refusal sets none). */
static int set_values(instance *c, const char *call, const plant_vr vr[], size_t n,
                             const double *values, int integer)
{
    size_t i;
    if (!lookup(c, call, vr, n, integer, values)) return PLANT_ERROR;
    if (n && (c->f.phase == TERMINATED || c->f.phase == ERROR)) {
        char names[MESSAGE] = "";
        size_t used = 0;
        for (i = 0; i < n && used < sizeof names - 64; i++)
            used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "",
                                     DFWB_MODEL_VARIABLES[vr[i]].name);
        return refuse(c, "%s of %s refused: not allowed in the %s state", call, names, PHASES[c->f.phase]);
    }
    for (i = 0; i < n; i++) {
        const model_variable *v = &DFWB_MODEL_VARIABLES[vr[i]];
        if (v->role == ROLE_INPUT) {
            if (!input_ok(c, values[i])) return PLANT_ERROR;
        } else if (v->role == ROLE_TIME) {
            return refuse(c, "%s: %s is the independent variable and cannot be set", call, v->name);
        } else if (v->role != ROLE_PARAMETER) {
            return refuse(c, "%s: %s is an output and cannot be set", call, v->name);
        } else if (c->f.phase == STEPPING) {
            return refuse(c, "%s of %s = %s refused: %s is a fixed parameter and cannot be set after "
                             "initialisation (%s stays %s)", call, v->name, repr_value(v, values[i]).s, v->name,
                          v->name, repr_value(v, c->f.values[vr[i]]).s);
        }
    }
    for (i = 0; i < n; i++) c->f.values[vr[i]] = values[i];
    return PLANT_OK;
}

int plant_fmu_set_reals(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, const double value[])
{
    return set_values(c, call, vr, n, value, 0);
}

int plant_fmu_set_integers(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, const int value[])
{
    double values[NVARS];
    size_t i;
    if (n > NVARS) return refuse(c, "%s: %zu valueReferences, this FMU has %zu variables", call, n, NVARS);
    for (i = 0; value && i < n; i++) values[i] = value[i];
    return set_values(c, call, vr, n, value ? values : NULL, 1);
}

int plant_fmu_no_variable(plant_fmu *c, const plant_vr vr[], size_t n, const char *kind)
{
    char list[MESSAGE] = "";
    size_t i, used = 0;
    if (n == 0) return PLANT_OK;
    for (i = 0; vr && i < n && used < sizeof list - 32; i++)
        used += (size_t)snprintf(list + used, sizeof list - used, "%s%u", i ? ", " : "", (unsigned)vr[i]);
    return refuse(c, "valueReferences [%s]: this FMU has no %s variable", list, kind);
}

/* -- FMU state ----------------------------------------------------------------------------------- */
/* What marks a state of this model (FNV-1a of its GUID): a handle of another FMU's state is refused. */
static uint64_t state_tag(void)
{
    uint64_t h = 14695981039346656037u;
    const char *p;
    for (p = DFWB_MODEL_GUID; *p; p++) h = (h ^ (unsigned char)*p) * 1099511628211u;
    return h;
}

/* The state behind a non-NULL handle, or NULL after a refusal: not a state of this model. */
static fmu_state *own_state(instance *c, const char *call, void *state)
{
    fmu_state *s = state;
    if (s->tag == state_tag()) return s;
    refuse(c, "%s: the state is not one of this FMU (%s): another FMU's, or freed", call, DFWB_MODEL_NAME);
    return NULL;
}

static void free_state(const instance *c, fmu_state *s)
{
    if (!s) return;
    dfwb_plant_free(s->solver);
    s->tag = 0;
    c->host.release(s);
}

int plant_fmu_get_state(plant_fmu *c, void **state)
{
    fmu_state *s;
    plant *copy = NULL;
    if (!state) return refuse(c, "getFMUstate: a NULL pointer for the state");
    if (!expect(c, "getFMUstate", ANY_BUT_ERROR)) return PLANT_ERROR;
    if (*state && !own_state(c, "getFMUstate", *state)) return PLANT_ERROR;
    if (c->solver && !(copy = dfwb_plant_copy(c->solver))) return refuse(c, "getFMUstate failed: out of memory");
    s = *state; /* a state given back is overwritten in place */
    if (s) {
        dfwb_plant_free(s->solver);
    } else if (!(s = allocate(c, sizeof *s))) {
        dfwb_plant_free(copy);
        return refuse(c, "getFMUstate failed: out of memory");
    }
    s->tag = state_tag();
    s->f = c->f;
    s->solver = copy;
    *state = s;
    return PLANT_OK;
}

/* The checks of SolverFMU._set_fmu_state on a state's facade values and solver; 0 after a refusal. */
static int state_ok(instance *c, const fmu_state *s)
{
    char err[MESSAGE];
    plant *fresh = NULL;
    size_t i;
    int same;
    const facade *f = &s->f;
    if (f->phase < INSTANTIATED || f->phase > TERMINATED ||
        (s->solver == NULL) != (f->phase == INSTANTIATED || f->phase == INITIALIZATION)) {
        refuse(c, "the state's phase does not match its solver");
        return 0;
    }
    for (i = 0; i < NVARS; i++) {
        const model_variable *v = &DFWB_MODEL_VARIABLES[i];
        if (settable(v) && v->integer && !(f->values[i] == floor(f->values[i]) && fabs(f->values[i]) < 2147483648.0)) {
            refuse(c, "the state's %s is not an int", v->name);
            return 0;
        }
    }
    if (!(isfinite(f->start) && isfinite(f->time))) {
        refuse(c, "the state's _start_time or _time is not a finite float");
        return 0;
    }
    if (!s->solver) return 1;
    if (new_solver(f, &fresh, err, sizeof err) != DFWB_OK) {
        refuse(c, "the state's parameters are refused: %s", err);
        return 0;
    }
    same = dfwb_plant_same_parameters(fresh, s->solver);
    dfwb_plant_free(fresh);
    if (!same) {
        refuse(c, "the state's solver does not match its parameters");
        return 0;
    }
    if (!(dfwb_plant_time(s->solver) == f->time - f->start)) {
        refuse(c, "the state's solver time does not match the state's time");
        return 0;
    }
    return 1;
}

int plant_fmu_set_state(plant_fmu *c, void *state)
{
    const fmu_state *s = state;
    plant *copy = NULL;
    if (!s) return refuse(c, "setFMUstate: a NULL state");
    if (!own_state(c, "setFMUstate", state) || !state_ok(c, s)) return PLANT_ERROR;
    if (s->solver && !(copy = dfwb_plant_copy(s->solver))) return refuse(c, "setFMUstate failed: out of memory");
    dfwb_plant_free(c->solver);
    c->solver = copy;
    c->f = s->f;
    c->frozen = 0; /* PlantFMU._restored */
    c->overflow = c->fourier_known = 0; /* nothing of this instance's run: a state before initialisation reads */
    memset(c->outputs, 0, sizeof c->outputs); /* as a reset instance, 0 */
    set_rotation(c);
    if (c->solver) refresh(c);
    return PLANT_OK;
}

int plant_fmu_free_state(plant_fmu *c, void **state)
{
    if (state && *state) {
        if (!own_state(c, "freeFMUstate", *state)) return PLANT_ERROR;
        free_state(c, *state);
        *state = NULL;
    }
    return PLANT_OK;
}

/* Serialized: "DFWBFMUS", u32 version, u32 plant kind, the GUID (40 bytes, NUL padded), then u64 fields: the
   phase, t0, t, the NVARS values, the solver's byte count (0: none), the solver's bytes, and a u32 CRC-32 of
   everything before it (so that bytes that are not exactly what an FMU wrote are refused at deserialization,
   whichever field a damage hits). */
#define MAGIC "DFWBFMUS"
#define FORMAT 2
#define SEAL 4 /* the trailing CRC-32 */
#define GUID_BYTES 40
#define FIXED (8 + 4 + 4 + GUID_BYTES + 8 * (3 + NVARS + 1))
#define MAX_SOLVER_BYTES ((size_t)1 << 16)

static void put_f64(unsigned char *p, double x)
{
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    dfwb_put_u64(p, u);
}

static double get_f64(const unsigned char *p)
{
    uint64_t u = dfwb_get_u64(p);
    double x;
    memcpy(&x, &u, sizeof x);
    return x;
}

static size_t solver_bytes(const plant *solver)
{
    size_t size = 0;
    if (!solver || dfwb_plant_to_bytes(solver, NULL, 0, &size, NULL, 0) != DFWB_OK) return 0;
    return size;
}

int plant_fmu_state_size(plant_fmu *c, void *state, size_t *size)
{
    if (!state || !size) return refuse(c, "serializedFMUstateSize: a NULL state or size");
    if (!own_state(c, "serializedFMUstateSize", state)) return PLANT_ERROR;
    *size = FIXED + solver_bytes(((const fmu_state *)state)->solver) + SEAL;
    return PLANT_OK;
}

int plant_fmu_serialize(plant_fmu *c, void *state, unsigned char out[], size_t size)
{
    const fmu_state *s = state;
    unsigned char *p = out;
    size_t i, n, needed;
    char err[MESSAGE];
    if (!s || !out) return refuse(c, "serializeFMUstate: a NULL state or buffer");
    if (!own_state(c, "serializeFMUstate", state)) return PLANT_ERROR;
    n = solver_bytes(s->solver);
    needed = FIXED + n + SEAL;
    if (size < needed)
        return refuse(c, "serializeFMUstate: a buffer of %zu bytes, the state takes %zu", size, needed);
    memset(p, 0, FIXED);
    memcpy(p, MAGIC, 8);
    p[8] = FORMAT;
    p[12] = DFWB_MODEL_KIND;
    memcpy(p + 16, DFWB_MODEL_GUID, strlen(DFWB_MODEL_GUID) < GUID_BYTES ? strlen(DFWB_MODEL_GUID) : GUID_BYTES);
    p += 16 + GUID_BYTES;
    dfwb_put_u64(p, (uint64_t)s->f.phase);
    put_f64(p + 8, s->f.start);
    put_f64(p + 16, s->f.time);
    for (i = 0; i < NVARS; i++) put_f64(p + 24 + 8 * i, s->f.values[i]);
    p += 24 + 8 * NVARS;
    dfwb_put_u64(p, (uint64_t)n);
    if (n && dfwb_plant_to_bytes(s->solver, p + 8, n, &n, err, sizeof err) != DFWB_OK)
        return refuse(c, "serializeFMUstate failed: %s", err);
    dfwb_put_u32(out + FIXED + n, dfwb_crc32(out, FIXED + n));
    return PLANT_OK;
}

int plant_fmu_deserialize(plant_fmu *c, const unsigned char in[], size_t size, void **state)
{
    const unsigned char *p = in;
    char guid[GUID_BYTES + 1] = {0}, err[MESSAGE];
    fmu_state *s;
    size_t i, n;
    uint64_t phase;
    plant *solver = NULL;
    if (!p || !state) return refuse(c, "deSerializeFMUstate: a NULL buffer or state pointer");
    if (*state && !own_state(c, "deSerializeFMUstate", *state)) return PLANT_ERROR;
    strncpy(guid, DFWB_MODEL_GUID, GUID_BYTES);
    if (size < FIXED + SEAL || memcmp(p, MAGIC, 8) != 0 ||
        dfwb_get_u64(p + 8) != (FORMAT | ((uint64_t)DFWB_MODEL_KIND << 32)))
        return refuse(c, "serialized state refused: not a state of a native %s FMU", DFWB_MODEL_NAME);
    if (memcmp(p + 16, guid, GUID_BYTES) != 0)
        return refuse(c, "serialized state refused: it was written by another build of %s", DFWB_MODEL_NAME);
    p += 16 + GUID_BYTES;
    phase = dfwb_get_u64(p);
    n = (size_t)dfwb_get_u64(p + 24 + 8 * NVARS);
    if (phase > TERMINATED || n > MAX_SOLVER_BYTES || size != FIXED + n + SEAL)
        return refuse(c, "serialized state refused: %zu bytes do not hold a state of this FMU", size);
    if (dfwb_get_u32(in + FIXED + n) != dfwb_crc32(in, FIXED + n))
        return refuse(c, "serialized state refused: its CRC-32 does not match its bytes (damaged)");
    if (n && dfwb_plant_from_bytes(DFWB_MODEL_KIND, p + 32 + 8 * NVARS, n, &solver, err, sizeof err) != DFWB_OK)
        return refuse(c, "serialized state refused: %s", err);
    s = *state ? (fmu_state *)*state : allocate(c, sizeof *s);
    if (!s) {
        dfwb_plant_free(solver);
        return refuse(c, "deSerializeFMUstate failed: out of memory");
    }
    if (*state) dfwb_plant_free(s->solver);
    s->tag = state_tag();
    s->f.phase = (int)phase;
    s->f.start = get_f64(p + 8);
    s->f.time = get_f64(p + 16);
    for (i = 0; i < NVARS; i++) s->f.values[i] = get_f64(p + 24 + 8 * i);
    s->solver = solver;
    *state = s;
    return PLANT_OK;
}

