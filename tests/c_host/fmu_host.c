/* Minimal FMI 2.0 co-simulation host, written in C so that no Python runs on the host side.

   usage: fmu_host DIR MODEL_ID STOP_TIME STEP [--state T] [VR=VALUE ...] [VR ...]

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

   Portable: on Windows (built with mingw-w64, run under Wine in the tests) it loads
   binaries/win64/MODEL_ID.dll with LoadLibrary; elsewhere binaries/linux64/MODEL_ID.so with dlopen.

   Build: cc -std=c99 -D_DEFAULT_SOURCE -I<fmpy>/c-code fmu_host.c -o fmu_host -ldl -lm
          x86_64-w64-mingw32-gcc -std=c99 -I<fmpy>/c-code fmu_host.c -o fmu_host.exe
   (headers: FMI 2.0, as shipped with fmpy)

   The host needs no Python environment (no LD_PRELOAD, no PYTHONHOME): dfwb's FMI shim in the
   FMU loads libpython itself (build_fmus/shim/fmi2_shim.c). */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define PLATFORM "win64"
#define SUFFIX ".dll"
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *find_symbol(void *library, const char *name) {
    return (void *)(size_t)GetProcAddress((HMODULE)library, name);
}
static const char *library_error(void) { return "LoadLibrary failed"; }
static char *absolute(const char *path, char *out, size_t size) { return _fullpath(out, path, size); }
#else
#include <dlfcn.h>
#define PLATFORM "linux64"
#define SUFFIX ".so"
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *find_symbol(void *library, const char *name) { return dlsym(library, name); }
static const char *library_error(void) { return dlerror(); }
static char *absolute(const char *path, char *out, size_t size) { (void)size; return realpath(path, out); }
#endif

#include "fmi2Functions.h"

#define MAX_VARS 64

static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInitializationMode;
    fmi2SetRealTYPE *setReal;
    fmi2ExitInitializationModeTYPE *exitInitializationMode;
    fmi2DoStepTYPE *doStep;
    fmi2GetRealTYPE *getReal;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2GetFMUstateTYPE *getFMUstate;
    fmi2SetFMUstateTYPE *setFMUstate;
    fmi2FreeFMUstateTYPE *freeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *serializedFMUstateSize;
    fmi2SerializeFMUstateTYPE *serializeFMUstate;
    fmi2DeSerializeFMUstateTYPE *deSerializeFMUstate;
} fmi;

static void die(const char *what, const char *detail) {
    fprintf(stderr, "fmu_host: %s%s\n", what, detail ? detail : "");
    exit(1);
}

/* Every FMI call goes through CHECK: a status other than fmi2OK (0) is fatal. */
#define CHECK(call)                                                                       \
    do {                                                                                  \
        fmi2Status status_ = (call);                                                      \
        if (status_ != fmi2OK) {                                                          \
            fprintf(stderr, "fmu_host: %s returned status %d\n", #call, (int)status_);   \
            exit(1);                                                                      \
        }                                                                                 \
    } while (0)

/* The FMU calls this with a finished message; it is printed verbatim (never used as a format). */
static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    fprintf(stderr, "[%s] status %d, %s: %s\n", instance ? instance : "?", (int)status,
            category ? category : "", message ? message : "");
}

/* math.isclose(a, b) as fmpy uses it: equal to a relative 1e-9 */
static int close_to(double a, double b) { return fabs(a - b) <= 1e-9 * fmax(fabs(a), fabs(b)); }

static void *symbol(void *library, const char *name) {
    void *address = find_symbol(library, name);
    if (!address) die("missing symbol ", name);
    return address;
}

/* The guid attribute of DIR/modelDescription.xml (fmi2Instantiate must be given it). */
static char *read_guid(const char *dir) {
    static char text[1 << 16], guid[128];
    char path[8192];
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    FILE *file = fopen(path, "rb");
    if (!file) die("cannot open ", path);
    size_t n = fread(text, 1, sizeof text - 1, file);
    fclose(file);
    text[n] = '\0';
    const char *start = strstr(text, " guid=\"");
    if (!start) die("no guid in ", path);
    start += strlen(" guid=\"");
    const char *end = strchr(start, '"');
    if (!end || end - start >= (long)sizeof guid) die("bad guid in ", path);
    memcpy(guid, start, (size_t)(end - start));
    guid[end - start] = '\0';
    return guid;
}

/* Print the row at t; step on the grid t0 + n * step from t = t_n to the stop time. */
static double run(fmi2Component c, long n, double t, double t0, double step, double stop, double state_time,
                  fmi2Byte **saved, size_t *saved_size, const fmi2ValueReference *out_vr, size_t n_out) {
    fmi2Real out_value[MAX_VARS];
    for (;; n++) {
        if (n_out) CHECK(fmi.getReal(c, out_vr, n_out, out_value));
        printf("%.17g", t);
        for (size_t k = 0; k < n_out; k++) printf(" %.17g", out_value[k]);
        printf("\n");
        if (saved && !*saved && t >= state_time) { /* the state at this row, as bytes */
            fmi2FMUstate state = NULL;
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
        CHECK(fmi.doStep(c, t, next - t, fmi2True));
        t = next;
    }
}

int main(int argc, char **argv) {
    if (argc < 5) die("usage: fmu_host DIR MODEL_ID STOP_TIME STEP [--state T] [VR=VALUE ...] [VR ...]", NULL);
    char dir[4096], path[8192], resources[8192];
    if (!absolute(argv[1], dir, sizeof dir)) die("no such directory: ", argv[1]);
    for (char *p = dir; *p; p++)
        if (*p == '\\') *p = '/';
    const char *id = argv[2];
    double stop = atof(argv[3]), step = atof(argv[4]), state_time = 0.0;
    int with_state = 0;
    if (!(step > 0.0)) die("STEP must be > 0", NULL);

    fmi2ValueReference in_vr[MAX_VARS], out_vr[MAX_VARS];
    fmi2Real in_value[MAX_VARS];
    size_t n_in = 0, n_out = 0;
    for (int i = 5; i < argc; i++) {
        char *equals = strchr(argv[i], '=');
        if (n_in == MAX_VARS || n_out == MAX_VARS) die("too many variables", NULL);
        if (strcmp(argv[i], "--state") == 0 && i + 1 < argc) {
            with_state = 1;
            state_time = atof(argv[++i]);
        } else if (equals) {
            in_vr[n_in] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
            in_value[n_in++] = atof(equals + 1);
        } else {
            out_vr[n_out++] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
        }
    }

    snprintf(path, sizeof path, "%s/binaries/" PLATFORM "/%s" SUFFIX, dir, id);
    void *library = open_library(path);
    if (!library) die("loading the binary failed: ", library_error());
#define LOAD(field, name) fmi.field = (name##TYPE *)symbol(library, #name)
    LOAD(instantiate, fmi2Instantiate);
    LOAD(setupExperiment, fmi2SetupExperiment);
    LOAD(enterInitializationMode, fmi2EnterInitializationMode);
    LOAD(setReal, fmi2SetReal);
    LOAD(exitInitializationMode, fmi2ExitInitializationMode);
    LOAD(doStep, fmi2DoStep);
    LOAD(getReal, fmi2GetReal);
    LOAD(terminate, fmi2Terminate);
    LOAD(freeInstance, fmi2FreeInstance);
    LOAD(getFMUstate, fmi2GetFMUstate);
    LOAD(setFMUstate, fmi2SetFMUstate);
    LOAD(freeFMUstate, fmi2FreeFMUstate);
    LOAD(serializedFMUstateSize, fmi2SerializedFMUstateSize);
    LOAD(serializeFMUstate, fmi2SerializeFMUstate);
    LOAD(deSerializeFMUstate, fmi2DeSerializeFMUstate);

    /* resourceLocation is a URI: file:// followed by the absolute path (no percent-encoding
       is done, so DIR must not contain characters that would need it, such as spaces). */
    snprintf(resources, sizeof resources, "file://%s%s/resources", dir[0] == '/' ? "" : "/", dir);
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi.instantiate(id, fmi2CoSimulation, read_guid(dir), resources, &callbacks,
                                      fmi2False, fmi2True /* loggingOn */);
    if (!c) die("fmi2Instantiate returned NULL", NULL);

    const double t0 = 0.0;
    CHECK(fmi.setupExperiment(c, fmi2False, 0.0, t0, fmi2True, stop));
    if (n_in) CHECK(fmi.setReal(c, in_vr, n_in, in_value));
    CHECK(fmi.enterInitializationMode(c));
    CHECK(fmi.exitInitializationMode(c));

    fmi2Byte *saved = NULL;
    size_t saved_size = 0;
    run(c, 0, t0, t0, step, stop, state_time, with_state ? &saved : NULL, &saved_size, out_vr, n_out);
    if (with_state) {
        fmi2FMUstate state = NULL;
        if (!saved) die("--state: the run never reached the state's time", NULL);
        fmi2Status cut = fmi.deSerializeFMUstate(c, saved, saved_size - 1, &state);
        printf("# the state cut by one byte: status %d\n", (int)cut);
        if (cut != fmi2Error || state) die("a state cut by one byte was not refused", NULL);
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
