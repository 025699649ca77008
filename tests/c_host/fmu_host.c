/* Minimal FMI 2.0 (or, built with -DFMI3, FMI 3.0) co-simulation host, written in C so that no Python runs on
   the host side.

   usage: fmu_host DIR MODEL_ID STOP_TIME STEP [--state T] [--guid G] [VR=VALUE ...] [VR ...]

   DIR is an extracted FMU; every VR=VALUE sets a Real start value (by value reference)
   before initialisation, every bare VR is a Real output to print. The host steps from
   t = 0 to STOP_TIME on the grid t_n = n * STEP exactly as fmpy's simulate_fmu does (same
   stop test, last step shortened to end at STOP_TIME), and prints "time out1 out2 ..." (%.17g) at t = 0 and
   after every step. Any status other than fmi2OK ends it with exit code 1 and a message
   on stderr; logging is on, so the FMU's own messages reach stderr too.

   --state T: at the first grid time >= T the host takes the FMU state, serializes it and frees it; at
   STOP_TIME it checks that the bytes cut by one are refused (fmi2Error), deserializes the bytes, sets the
   state, prints "# restored at <time>" and steps to STOP_TIME again, printing the same rows if the round
   trip is exact.
   --guid G: instantiate with G instead of the model description's guid (instantiationToken).

   Portable: on Windows (built with mingw-w64, run under Wine in the tests) it loads
   binaries/win64/MODEL_ID.dll with LoadLibrary; elsewhere binaries/linux64/MODEL_ID.so with dlopen (FMI 3.0:
   binaries/x86_64-windows/, binaries/x86_64-linux/). The FMI version's calls are behind one small table
   (fmi below), so the run itself is written once.

   Build: cc -std=c99 -D_DEFAULT_SOURCE -I<fmpy>/c-code fmu_host.c -o fmu_host -ldl -lm
          x86_64-w64-mingw32-gcc -std=c99 -I<fmpy>/c-code fmu_host.c -o fmu_host.exe
   (add -DFMI3 for FMI 3.0; headers as shipped with fmpy)

   The host needs no Python environment (no LD_PRELOAD, no PYTHONHOME): dfwb's FMI shim in the
   FMU loads libpython itself (build_fmus/shim/fmi2_shim.c). */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define SUFFIX ".dll"
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *find_symbol(void *library, const char *name) {
    return (void *)(size_t)GetProcAddress((HMODULE)library, name);
}
static const char *library_error(void) { return "LoadLibrary failed"; }
static char *absolute(const char *path, char *out, size_t size) { return _fullpath(out, path, size); }
#else
#include <dlfcn.h>
#define SUFFIX ".so"
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *find_symbol(void *library, const char *name) { return dlsym(library, name); }
static const char *library_error(void) { return dlerror(); }
static char *absolute(const char *path, char *out, size_t size) { (void)size; return realpath(path, out); }
#endif

#ifdef FMI3
#include "fmi3Functions.h"
#ifdef _WIN32
#define PLATFORM "x86_64-windows"
#else
#define PLATFORM "x86_64-linux"
#endif
#define TOKEN_ATTRIBUTE " instantiationToken=\""
typedef fmi3Instance instance;
typedef fmi3FMUState fmu_state;
typedef fmi3ValueReference value_reference;
typedef fmi3Float64 real;
typedef fmi3Byte state_byte;
#define STATUS_OK fmi3OK
#define STATUS_ERROR fmi3Error
#else
#include "fmi2Functions.h"
#ifdef _WIN32
#define PLATFORM "win64"
#else
#define PLATFORM "linux64"
#endif
#define TOKEN_ATTRIBUTE " guid=\""
typedef fmi2Component instance;
typedef fmi2FMUstate fmu_state;
typedef fmi2ValueReference value_reference;
typedef fmi2Real real;
typedef fmi2Byte state_byte;
#define STATUS_OK fmi2OK
#define STATUS_ERROR fmi2Error
#endif

#define MAX_VARS 64

/* The FMU's functions: the same names for both versions (FMI 3.0's getFloat64 is getReal here, ...). */
#ifdef FMI3
#define V(fmi2name, fmi3name) fmi3name
#else
#define V(fmi2name, fmi3name) fmi2name
#endif
#define FUNCTIONS(X)                                                                                      \
    X(setReal, V(fmi2SetReal, fmi3SetFloat64))                                                            \
    X(getReal, V(fmi2GetReal, fmi3GetFloat64))                                                            \
    X(enterInitializationMode, V(fmi2EnterInitializationMode, fmi3EnterInitializationMode))              \
    X(exitInitializationMode, V(fmi2ExitInitializationMode, fmi3ExitInitializationMode))                 \
    X(doStep, V(fmi2DoStep, fmi3DoStep))                                                                  \
    X(terminate, V(fmi2Terminate, fmi3Terminate))                                                         \
    X(freeInstance, V(fmi2FreeInstance, fmi3FreeInstance))                                                \
    X(getFMUstate, V(fmi2GetFMUstate, fmi3GetFMUState))                                                   \
    X(setFMUstate, V(fmi2SetFMUstate, fmi3SetFMUState))                                                   \
    X(freeFMUstate, V(fmi2FreeFMUstate, fmi3FreeFMUState))                                                \
    X(serializedFMUstateSize, V(fmi2SerializedFMUstateSize, fmi3SerializedFMUStateSize))                  \
    X(serializeFMUstate, V(fmi2SerializeFMUstate, fmi3SerializeFMUState))                                 \
    X(deSerializeFMUstate, V(fmi2DeSerializeFMUstate, fmi3DeserializeFMUState))
#define PASTE(a, b) a##b
#define TYPE_OF(name) PASTE(name, TYPE)
#define FIELD(field, name) TYPE_OF(name) *field;
static struct {
    FUNCTIONS(FIELD)
#ifdef FMI3
    fmi3InstantiateCoSimulationTYPE *instantiate;
#else
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setupExperiment;
#endif
} fmi;

static void die(const char *what, const char *detail) {
    fprintf(stderr, "fmu_host: %s%s\n", what, detail ? detail : "");
    exit(1);
}

/* Every FMI call goes through CHECK: a status other than fmi2OK (0) is fatal. */
#define CHECK(call)                                                                       \
    do {                                                                                  \
        int status_ = (int)(call);                                                        \
        if (status_ != STATUS_OK) {                                                          \
            fprintf(stderr, "fmu_host: %s returned status %d\n", #call, (int)status_);   \
            exit(1);                                                                      \
        }                                                                                 \
    } while (0)

/* The FMU calls this with a finished message; it is printed verbatim (never used as a format). */
static const char *instance_name = "?";
#ifdef FMI3
static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
#else
static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    (void)name;
#endif
    fprintf(stderr, "[%s] status %d, %s: %s\n", instance_name, (int)status, category ? category : "",
            message ? message : "");
}

/* math.isclose(a, b) as fmpy uses it: equal to a relative 1e-9 */
static int close_to(double a, double b) { return fabs(a - b) <= 1e-9 * fmax(fabs(a), fabs(b)); }

static void *symbol(void *library, const char *name) {
    void *address = find_symbol(library, name);
    if (!address) die("missing symbol ", name);
    return address;
}

/* The guid (FMI 3.0: instantiationToken) of DIR/modelDescription.xml (the FMU must be instantiated with it). */
static char *read_guid(const char *dir) {
    static char text[1 << 16], guid[128];
    char path[8192];
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    FILE *file = fopen(path, "rb");
    if (!file) die("cannot open ", path);
    size_t n = fread(text, 1, sizeof text - 1, file);
    fclose(file);
    text[n] = '\0';
    const char *start = strstr(text, TOKEN_ATTRIBUTE);
    if (!start) die("no guid or instantiationToken in ", path);
    start += strlen(TOKEN_ATTRIBUTE);
    const char *end = strchr(start, '"');
    if (!end || end - start >= (long)sizeof guid) die("bad guid in ", path);
    memcpy(guid, start, (size_t)(end - start));
    guid[end - start] = '\0';
    return guid;
}

/* The calls whose arguments differ between the versions. */
static int get_reals(instance c, const value_reference *vr, size_t n, real *values) {
#ifdef FMI3
    return (int)fmi.getReal(c, vr, n, values, n);
#else
    return (int)fmi.getReal(c, vr, n, values);
#endif
}

static int set_reals(instance c, const value_reference *vr, size_t n, const real *values) {
#ifdef FMI3
    return (int)fmi.setReal(c, vr, n, values, n);
#else
    return (int)fmi.setReal(c, vr, n, values);
#endif
}

static int do_step(instance c, double t, double h) {
#ifdef FMI3
    fmi3Boolean event, terminate, early;
    fmi3Float64 reached;
    return (int)fmi.doStep(c, t, h, fmi3True, &event, &terminate, &early, &reached);
#else
    return (int)fmi.doStep(c, t, h, fmi2True);
#endif
}

static instance instantiate(const char *id, const char *token, const char *dir) {
    char resources[8300];
#ifdef FMI3
    snprintf(resources, sizeof resources, "%s/resources/", dir); /* a path, not a URI */
    return fmi.instantiate(id, token, resources, fmi3False, fmi3True /* loggingOn */, fmi3False, fmi3False, NULL,
                           0, NULL, logger, NULL);
#else
    /* resourceLocation is a URI: file:// followed by the absolute path (no percent-encoding
       is done, so DIR must not contain characters that would need it, such as spaces). */
    static fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    snprintf(resources, sizeof resources, "file://%s%s/resources", dir[0] == '/' ? "" : "/", dir);
    return fmi.instantiate(id, fmi2CoSimulation, token, resources, &callbacks, fmi2False, fmi2True /* loggingOn */);
#endif
}

static int enter_initialization(instance c, double t0, double stop) {
#ifdef FMI3
    return (int)fmi.enterInitializationMode(c, fmi3False, 0.0, t0, fmi3True, stop);
#else
    int status = (int)fmi.setupExperiment(c, fmi2False, 0.0, t0, fmi2True, stop);
    return status == STATUS_OK ? (int)fmi.enterInitializationMode(c) : status;
#endif
}

/* Print the row at t; step on the grid t0 + n * step from t = t_n to the stop time. */
static double run(instance c, long n, double t, double t0, double step, double stop, double state_time,
                  state_byte **saved, size_t *saved_size, const value_reference *out_vr, size_t n_out) {
    real out_value[MAX_VARS];
    for (;; n++) {
        if (n_out) CHECK(get_reals(c, out_vr, n_out, out_value));
        printf("%.17g", t);
        for (size_t k = 0; k < n_out; k++) printf(" %.17g", out_value[k]);
        printf("\n");
        if (saved && !*saved && t >= state_time) { /* the state at this row, as bytes */
            fmu_state state = NULL;
            CHECK(fmi.getFMUstate(c, &state));
            CHECK(fmi.serializedFMUstateSize(c, state, saved_size));
            *saved = malloc(*saved_size);
            if (!*saved) die("out of memory", NULL);
            CHECK(fmi.serializeFMUstate(c, state, *saved, *saved_size));
            CHECK(fmi.freeFMUstate(c, &state));
            printf("# state at %.17g: %lu bytes, step %ld\n", t, (unsigned long)*saved_size, n);
        }
        if (t > stop || close_to(t, stop)) return t;
        double next = t0 + (double)(n + 1) * step;
        if (next > stop && !close_to(next, stop)) next = stop;
        CHECK(do_step(c, t, next - t));
        t = next;
    }
}

int main(int argc, char **argv) {
    if (argc < 5) die("usage: fmu_host DIR MODEL_ID STOP_TIME STEP [--state T] [--guid G] [VR=VALUE ...] [VR ...]", NULL);
    char dir[4096], path[8192];
    if (!absolute(argv[1], dir, sizeof dir)) die("no such directory: ", argv[1]);
    for (char *p = dir; *p; p++)
        if (*p == '\\') *p = '/';
    const char *id = argv[2];
    double stop = atof(argv[3]), step = atof(argv[4]), state_time = 0.0;
    const char *guid = NULL;
    int with_state = 0;
    if (!(step > 0.0)) die("STEP must be > 0", NULL);

    value_reference in_vr[MAX_VARS], out_vr[MAX_VARS];
    real in_value[MAX_VARS];
    size_t n_in = 0, n_out = 0;
    for (int i = 5; i < argc; i++) {
        char *equals = strchr(argv[i], '=');
        if (n_in == MAX_VARS || n_out == MAX_VARS) die("too many variables", NULL);
        if (strcmp(argv[i], "--guid") == 0 && i + 1 < argc) {
            guid = argv[++i];
        } else if (strcmp(argv[i], "--state") == 0 && i + 1 < argc) {
            with_state = 1;
            state_time = atof(argv[++i]);
        } else if (equals) {
            in_vr[n_in] = (value_reference)strtoul(argv[i], NULL, 10);
            in_value[n_in++] = atof(equals + 1);
        } else {
            out_vr[n_out++] = (value_reference)strtoul(argv[i], NULL, 10);
        }
    }

    snprintf(path, sizeof path, "%s/binaries/" PLATFORM "/%s" SUFFIX, dir, id);
    void *library = open_library(path);
    if (!library) die("loading the binary failed: ", library_error());
#define NAME_OF(name) STRING(name)
#define STRING(name) #name
#define LOAD(field, name) fmi.field = (TYPE_OF(name) *)symbol(library, NAME_OF(name));
    FUNCTIONS(LOAD)
#ifdef FMI3
    LOAD(instantiate, fmi3InstantiateCoSimulation)
#else
    LOAD(instantiate, fmi2Instantiate)
    LOAD(setupExperiment, fmi2SetupExperiment)
#endif

    instance_name = id;
    instance c = instantiate(id, guid ? guid : read_guid(dir), dir);
    if (!c) die("the FMU's instantiation returned NULL", NULL);

    const double t0 = 0.0;
    if (n_in) CHECK(set_reals(c, in_vr, n_in, in_value));
    CHECK(enter_initialization(c, t0, stop));
    CHECK(fmi.exitInitializationMode(c));

    state_byte *saved = NULL;
    size_t saved_size = 0;
    run(c, 0, t0, t0, step, stop, state_time, with_state ? &saved : NULL, &saved_size, out_vr, n_out);
    if (with_state) {
        fmu_state state = NULL;
        if (!saved) die("--state: the run never reached the state's time", NULL);
        int cut = (int)fmi.deSerializeFMUstate(c, saved, saved_size - 1, &state);
        printf("# the state cut by one byte: status %d\n", cut);
        if (cut != STATUS_ERROR || state) die("a state cut by one byte was not refused", NULL);
        CHECK(fmi.deSerializeFMUstate(c, saved, saved_size, &state));
        CHECK(fmi.setFMUstate(c, state));
        CHECK(fmi.freeFMUstate(c, &state));
        long n = 0;
        double t = t0;
        while (t < state_time) t = t0 + (double)++n * step; /* the grid point the state was taken at */
        printf("# restored at %.17g\n", t);
        run(c, n, t, t0, step, stop, state_time, NULL, NULL, out_vr, n_out);
        free(saved);
    }

    CHECK(fmi.terminate(c));
    fmi.freeInstance(c);
    return 0;
}
