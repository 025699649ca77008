/* Minimal FMI 2.0 co-simulation host, written in C so that no Python runs on the host side.

   usage: fmu_host DIR MODEL_ID STOP_TIME STEP [VR=VALUE ...] [VR ...]

   DIR is an extracted FMU; every VR=VALUE sets a Real start value (by value reference)
   before initialisation, every bare VR is a Real output to print. The host steps from
   t = 0 to STOP_TIME on the grid t_n = n * STEP exactly as fmpy's simulate_fmu does (same
   stop test, last step shortened to end at STOP_TIME), and prints "time out1 out2 ..." (%.17g) at t = 0 and
   after every step. Any status other than fmi2OK ends it with exit code 1 and a message
   on stderr; logging is on, so the FMU's own messages reach stderr too.

   Build: cc -I<fmpy>/c-code fmu_host.c -o fmu_host -ldl -lm   (headers: FMI 2.0, as shipped with fmpy)

   The host needs no Python environment (no LD_PRELOAD, no PYTHONHOME): dfwb's FMI shim in the
   FMU loads libpython itself (build_fmus/shim/fmi2_shim.c). */

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
    void *address = dlsym(library, name);
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

int main(int argc, char **argv) {
    if (argc < 5) die("usage: fmu_host DIR MODEL_ID STOP_TIME STEP [VR=VALUE ...] [VR ...]", NULL);
    char dir[4096], path[8192], resources[8192];
    if (!realpath(argv[1], dir)) die("no such directory: ", argv[1]);
    const char *id = argv[2];
    double stop = atof(argv[3]), step = atof(argv[4]);
    if (!(step > 0.0)) die("STEP must be > 0", NULL);

    fmi2ValueReference in_vr[MAX_VARS], out_vr[MAX_VARS];
    fmi2Real in_value[MAX_VARS], out_value[MAX_VARS];
    size_t n_in = 0, n_out = 0;
    for (int i = 5; i < argc; i++) {
        char *equals = strchr(argv[i], '=');
        if (n_in == MAX_VARS || n_out == MAX_VARS) die("too many variables", NULL);
        if (equals) {
            in_vr[n_in] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
            in_value[n_in++] = atof(equals + 1);
        } else {
            out_vr[n_out++] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
        }
    }

    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) die("dlopen failed: ", dlerror());
    fmi.instantiate = (fmi2InstantiateTYPE *)symbol(library, "fmi2Instantiate");
    fmi.setupExperiment = (fmi2SetupExperimentTYPE *)symbol(library, "fmi2SetupExperiment");
    fmi.enterInitializationMode = (fmi2EnterInitializationModeTYPE *)symbol(library, "fmi2EnterInitializationMode");
    fmi.setReal = (fmi2SetRealTYPE *)symbol(library, "fmi2SetReal");
    fmi.exitInitializationMode = (fmi2ExitInitializationModeTYPE *)symbol(library, "fmi2ExitInitializationMode");
    fmi.doStep = (fmi2DoStepTYPE *)symbol(library, "fmi2DoStep");
    fmi.getReal = (fmi2GetRealTYPE *)symbol(library, "fmi2GetReal");
    fmi.terminate = (fmi2TerminateTYPE *)symbol(library, "fmi2Terminate");
    fmi.freeInstance = (fmi2FreeInstanceTYPE *)symbol(library, "fmi2FreeInstance");

    /* resourceLocation is a URI: file:// followed by the absolute path (no percent-encoding
       is done, so DIR must not contain characters that would need it, such as spaces). */
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi.instantiate(id, fmi2CoSimulation, read_guid(dir), resources, &callbacks,
                                      fmi2False, fmi2True /* loggingOn */);
    if (!c) die("fmi2Instantiate returned NULL", NULL);

    const double t0 = 0.0;
    CHECK(fmi.setupExperiment(c, fmi2False, 0.0, t0, fmi2True, stop));
    if (n_in) CHECK(fmi.setReal(c, in_vr, n_in, in_value));
    CHECK(fmi.enterInitializationMode(c));
    CHECK(fmi.exitInitializationMode(c));

    double t = t0;
    for (long n = 0;; n++) {
        if (n_out) CHECK(fmi.getReal(c, out_vr, n_out, out_value));
        printf("%.17g", t);
        for (size_t k = 0; k < n_out; k++) printf(" %.17g", out_value[k]);
        printf("\n");
        if (t > stop || close_to(t, stop)) break;
        double next = t0 + (double)(n + 1) * step;
        if (next > stop && !close_to(next, stop)) next = stop;
        CHECK(fmi.doStep(c, t, next - t, fmi2True));
        t = next;
    }

    CHECK(fmi.terminate(c));
    fmi.freeInstance(c);
    return 0;
}
