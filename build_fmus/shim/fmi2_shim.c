/* dfwb FMI 2.0 co-simulation shim: binaries/linux64/<model>.so and binaries/win64/<model>.dll of every
   pythonfmu-built dfwb FMU.

   pythonfmu 0.7.0's own binary sits next to this one as <model>.pythonfmu.so (.dll); every fmi2
   function of FMI 2.0 co-simulation is exported here and forwarded to it. The shim adds:

   1. Errors are fmi2Error. The inner FMU is instantiated with the shim's callbacks (its
      logging always on) and the worst status logged during each forwarded call is kept: a
      call that returned fmi2OK, fmi2Warning or fmi2Discard while a message of status
      fmi2Error was logged returns fmi2Error. Messages of status fmi2Warning or worse always
      reach the host's logger; fmi2OK messages only while the host has logging on
      (fmi2Instantiate's loggingOn, fmi2SetDebugLogging). Log categories are not filtered:
      fmi2SetDebugLogging's list is ignored, only its loggingOn flag counts. A '%' in a
      message is doubled (the host's logger takes the message as a printf format).

   2. The FMI 2.0 state machine. After a call returned fmi2Error the instance is in the
      Error state: only fmi2Reset, fmi2FreeInstance, fmi2SetFMUstate, fmi2GetFMUstate,
      fmi2FreeFMUstate, the serialization functions, fmi2SetDebugLogging and the getters
      (fmi2Get<Type>, fmi2Get*Status, for diagnosis) are forwarded; any other call returns
      fmi2Error with a message naming it. fmi2Reset and a successful fmi2SetFMUstate leave
      the Error state. After fmi2Terminate only fmi2Reset, fmi2FreeInstance, the getters
      and the state functions are accepted. After an inner fmi2Fatal (pythonfmu has then
      released its Python objects) everything but fmi2FreeInstance returns fmi2Fatal, and
      fmi2FreeInstance frees only the shim's memory: pythonfmu's instance is leaked on
      purpose, because freeing it would release those objects a second time.

   3. No Python runtime in the host. pythonfmu's binary embeds CPython without linking
      libpython. If the process has no Py_IsInitialized, fmi2Instantiate loads a libpython
      (RTLD_GLOBAL) before the inner binary: first the one named on the first line of
      resources/dfwb_python.txt (the Python that built the FMU), then libpython3.13.so.1.0
      down to libpython3.10.so.1.0 from the default library path. Unless PYTHONHOME is set,
      the home of the loaded library (the nearest ancestor folder with lib/python3.X/os.py)
      is given to Py_SetPythonHome, so no environment variable is needed. If no libpython
      loads, fmi2Instantiate logs one fmi2Fatal message and returns NULL.
      On Windows pythonfmu's DLL imports python3.dll itself (and the MSVC runtime): Windows finds them on
      the DLL search path (a Python 3 installation's folder on PATH); if it does not, fmi2Instantiate logs
      one fmi2Fatal message naming the DLL and the Windows error, and returns NULL.

   4. Arguments are checked before pythonfmu sees them (it would crash, or fail with fmi2Fatal):
      fmi2Instantiate returns NULL, with one fmi2Fatal message, for a fmuType other than
      fmi2CoSimulation, a fmuGUID other than the guid in <resources>/../modelDescription.xml and
      a resource folder without pythonfmu's slavemodule.txt and the script it names. pythonfmu
      gets the instance name with every byte that is not UTF-8 replaced by '?' ("" for NULL), and
      the resource folder as file://<decoded path> (it decodes only %20, only in file:// URIs).
      fmi2Error (the Error state): a NULL array with nvr > 0 in a getter or setter, a NULL or
      non-UTF-8 string in fmi2SetString, a NULL value of fmi2Get*Status, a NULL FMU state or
      pointer to one, a deserialization from NULL or of more than MAX_STATE_BYTES bytes, a
      serialization buffer smaller than fmi2SerializedFMUstateSize. fmi2FreeFMUstate sets
      *FMUstate to NULL (a second free is then ignored, as a NULL state is). fmi2SerializeFMUstate
      serializes into a buffer of the exact size and copies it (pythonfmu copies `size` bytes,
      reading past its own bytes when the host's buffer is larger).

   5. A serialized state is refused at fmi2DeSerializeFMUstate, as the native FMUs refuse it: pythonfmu
      reads the bytes with a class method that cannot log, and the facade turns bytes it refuses (not a
      state, another model's or build's, truncated, extended, damaged: fmus/state.py checks a SHA-256)
      into a placeholder that serializes as "dfwb-fmu-state\nrefused: <why>". The shim serializes each
      state it deserialized once more, and for such a placeholder frees it, logs the reason and returns
      fmi2Error; the host's *FMUstate is then left as it was (it is replaced only by an accepted state).

   Build: cc -shared -fPIC -O2 -fvisibility=hidden -I<fmpy>/c-code -o <model>.so fmi2_shim.c -ldl -lpthread
          x86_64-w64-mingw32-gcc -shared -O2 -static-libgcc -I<fmpy>/c-code -o <model>.dll fmi2_shim.c */

#ifndef _WIN32
#define _GNU_SOURCE
#endif
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <wchar.h>

#include "fmi2Functions.h"

/* What differs between the platforms: loading a library and finding a function in it, this library's own
   path, the lock around the first load, and how a resource URI names a folder. */
#ifdef _WIN32
#include <windows.h>
#define INNER_SUFFIX ".pythonfmu.dll"
#define OWN_SUFFIX ".dll"
#ifndef PATH_MAX
#define PATH_MAX MAX_PATH
#endif
static void *open_inner(const char *path) { return (void *)LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH); }
static void *find(void *library, const char *name) { return (void *)(size_t)GetProcAddress((HMODULE)library, name); }
static const char *load_error(void) {
    static char text[300];
    DWORD code = GetLastError();
    snprintf(text, sizeof text, "Windows error %lu%s", (unsigned long)code,
             code == ERROR_MOD_NOT_FOUND ? " (a DLL it needs is not on the DLL search path: python3.dll of a "
                                           "Python 3 installation on PATH, and the MSVC runtime)" : "");
    return text;
}
static SRWLOCK load_lock = SRWLOCK_INIT;
static void lock(void) { AcquireSRWLockExclusive(&load_lock); }
static void unlock(void) { ReleaseSRWLockExclusive(&load_lock); }
#else
#include <dlfcn.h>
#include <pthread.h>
#define INNER_SUFFIX ".pythonfmu.so"
#define OWN_SUFFIX ".so"
static void *open_inner(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *find(void *library, const char *name) { return dlsym(library, name); }
static const char *load_error(void) {
    const char *error = dlerror();
    return error ? error : "?";
}
static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static void lock(void) { pthread_mutex_lock(&load_lock); }
static void unlock(void) { pthread_mutex_unlock(&load_lock); }
#endif
#define PYTHON_RECORD "dfwb_python.txt"
#define PHASE_VR 0x7FFFFFFFu /* the facade's private integer: its phase (fmus/facade.py PHASE_VR) */
#define MAX_STATE_BYTES ((size_t)1 << 20) /* a serialized state is at most tens of kB; fmus/state.py: 256 kB */

/* ------------------------------------------------------------------ the inner binary */

#define INNER_FUNCTIONS(X)                                                                   \
    X(fmi2SetDebugLogging) X(fmi2Instantiate) X(fmi2FreeInstance) X(fmi2SetupExperiment)     \
    X(fmi2EnterInitializationMode) X(fmi2ExitInitializationMode) X(fmi2Terminate)            \
    X(fmi2Reset) X(fmi2GetReal) X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString)         \
    X(fmi2SetReal) X(fmi2SetInteger) X(fmi2SetBoolean) X(fmi2SetString) X(fmi2GetFMUstate)   \
    X(fmi2SetFMUstate) X(fmi2FreeFMUstate) X(fmi2SerializedFMUstateSize)                     \
    X(fmi2SerializeFMUstate) X(fmi2DeSerializeFMUstate) X(fmi2GetDirectionalDerivative)      \
    X(fmi2SetRealInputDerivatives) X(fmi2GetRealOutputDerivatives) X(fmi2DoStep)             \
    X(fmi2CancelStep) X(fmi2GetStatus) X(fmi2GetRealStatus) X(fmi2GetIntegerStatus)          \
    X(fmi2GetBooleanStatus) X(fmi2GetStringStatus)

#define FIELD(name) name##TYPE *name;
static struct { INNER_FUNCTIONS(FIELD) } inner;
#undef FIELD

static void *inner_library;

static void locate_self(void) {}

/* ------------------------------------------------------------------ an instance */

enum phase { INSTANTIATED, INITIALIZING, STEPPING, TERMINATED };

typedef struct {
    fmi2Component inner;                  /* pythonfmu's instance */
    fmi2CallbackFunctions host;           /* the host's callbacks (copied) */
    fmi2CallbackFunctions own;            /* given to pythonfmu: it keeps a pointer to them */
    char *name;
    int logging_on;                       /* the host's wish for fmi2OK messages */
    int worst;                            /* worst status logged during the current call */
    int error;                            /* in the FMI Error state */
    int fatal;                            /* pythonfmu returned fmi2Fatal: its instance is unusable */
    enum phase phase;
} Shim;

/* Pass one message to the host's logger (the message is text: '%' doubled for its printf). */
static void to_host(Shim *s, fmi2Status status, const char *category, const char *message) {
    if (!s->host.logger) return;
    if (status < fmi2Warning && !s->logging_on) return;
    const char *text = message ? message : "";
    char *escaped = NULL;
    if (strchr(text, '%')) {
        size_t n = strlen(text);
        escaped = malloc(2 * n + 1);
        if (escaped) {
            char *out = escaped;
            for (const char *p = text; *p; p++) {
                *out++ = *p;
                if (*p == '%') *out++ = '%';
            }
            *out = '\0';
            text = escaped;
        } else {
            text = "(a message with '%' that could not be copied)";
        }
    }
    s->host.logger(s->host.componentEnvironment, s->name ? s->name : "", status, category ? category : "", text);
    free(escaped);
}

/* The logger pythonfmu calls (its messages carry no format arguments: taken as text). */
static void inner_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                         fmi2String category, fmi2String message, ...) {
    (void)instance;
    Shim *s = (Shim *)env;
    if (!s) return;
    if ((int)status > s->worst && status <= fmi2Pending) s->worst = (int)status;
    to_host(s, status, category, message);
}

static void shim_log(Shim *s, fmi2Status status, const char *format, ...) {
    char text[2048];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    to_host(s, status, status >= fmi2Error ? "logStatusError" : "logAll", text);
}

/* ------------------------------------------------------------------ call discipline */

enum rule {
    ANYTIME,      /* getters, state functions, debug logging: also in the Error state */
    NORMAL,       /* refused in the Error state and after fmi2Terminate */
};

/* Whether call `what` may go to pythonfmu; if not, *refused is the status to return. */
static int admit(Shim *s, const char *what, enum rule rule, fmi2Status *refused) {
    if (!s) return 0;
    if (s->fatal) {
        shim_log(s, fmi2Fatal, "%s: the FMU had a fatal error; only fmi2FreeInstance may be called", what);
        *refused = fmi2Fatal;
        return 0;
    }
    if (rule == ANYTIME) return 1;
    if (s->error) {
        shim_log(s, fmi2Error, "%s: the FMU is in the error state; call fmi2Reset, fmi2SetFMUstate or "
                 "fmi2FreeInstance", what);
        *refused = fmi2Error;
        return 0;
    }
    if (s->phase == TERMINATED) {
        shim_log(s, fmi2Error, "%s: the FMU is terminated; only fmi2Reset, fmi2FreeInstance and the getters "
                 "may be called", what);
        s->error = 1;
        *refused = fmi2Error;
        return 0;
    }
    return 1;
}

/* The status of a forwarded call, from pythonfmu's and the worst one logged during it. */
static fmi2Status settle(Shim *s, const char *what, fmi2Status status) {
    if (status == fmi2Fatal) {
        s->fatal = 1;
        shim_log(s, fmi2Fatal, "%s: fatal error inside the FMU; only fmi2FreeInstance may be called", what);
        return fmi2Fatal;
    }
    if ((status == fmi2OK || status == fmi2Warning || status == fmi2Discard) && s->worst >= fmi2Error)
        status = fmi2Error;
    if (status == fmi2Error) s->error = 1;
    return status;
}

#define BEGIN(s) ((s)->worst = fmi2OK)

#define FORWARD(c, function, rule, ...)                                                     \
    Shim *s = (Shim *)(c);                                                                  \
    fmi2Status refused = fmi2Error;                                                         \
    if (!s) return fmi2Error;                                                               \
    if (!admit(s, #function, rule, &refused)) return refused;                               \
    if (!inner.function) {                                                                  \
        shim_log(s, fmi2Error, "%s is not provided by the FMU", #function);                 \
        s->error = 1;                                                                       \
        return fmi2Error;                                                                   \
    }                                                                                       \
    BEGIN(s);                                                                               \
    fmi2Status status = settle(s, #function, inner.function(s->inner, __VA_ARGS__));

/* Refuse a call for a bad argument: fmi2Error with a message, the Error state. */
static fmi2Status refuse(Shim *s, const char *what, const char *why) {
    shim_log(s, fmi2Error, "%s: %s", what, why);
    s->error = 1;
    return fmi2Error;
}

/* ------------------------------------------------------------------ Python runtime */

/* The folder of resources, from a file: URI (file:///a/b, file:/a/b; %XX decoded). */
static int resource_folder(const char *uri, char *out, size_t size) {
    if (!uri) return 0;
    const char *p = uri;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (*p != '/') { /* file://host/path: only localhost */
            if (strncmp(p, "localhost/", 10) != 0) return 0;
            p += 9;
        }
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
    size_t n = 0;
    for (; *p && n + 1 < size; p++) {
        unsigned int byte;
        if (p[0] == '%' && p[1] && p[2] && sscanf(p + 1, "%2x", &byte) == 1) {
            out[n++] = (char)byte;
            p += 2;
        } else {
            out[n++] = *p;
        }
    }
    out[n] = '\0';
    while (n > 1 && out[n - 1] == '/') out[--n] = '\0';
#ifdef _WIN32
    if (n > 2 && out[0] == '/' && out[2] == ':') memmove(out, out + 1, n--); /* file:///C:/a: C:/a */
#endif
    return n > 0;
}

static int is_file(const char *path) {
    struct stat info;
    return stat(path, &info) == 0 && S_ISREG(info.st_mode);
}

#ifdef _WIN32
/* pythonfmu's DLL imports python3.dll: Windows loads it with the DLL (see 3. above). */
static int ensure_python(const char *resources, char *why, size_t size) {
    (void)resources, (void)why, (void)size;
    return 1;
}
#else
/* Py_SetPythonHome(<ancestor of the library with lib/python3.X/os.py>) unless PYTHONHOME is set. */
static void set_python_home(void *python) {
    static wchar_t home_w[PATH_MAX];
    if (getenv("PYTHONHOME")) return;
    const char *(*get_version)(void) = (const char *(*)(void))dlsym(python, "Py_GetVersion");
    void *any = dlsym(python, "Py_IsInitialized");
    Dl_info info;
    if (!get_version || !any || !dladdr(any, &info) || !info.dli_fname) return;
    int major = 0, minor = 0;
    if (sscanf(get_version(), "%d.%d", &major, &minor) != 2) return;
    char folder[PATH_MAX];
    if (!realpath(info.dli_fname, folder)) snprintf(folder, sizeof folder, "%s", info.dli_fname);
    for (int level = 0; level < 5; level++) {
        char *slash = strrchr(folder, '/');
        if (!slash) return;
        *slash = '\0';
        char landmark[PATH_MAX + 64];
        snprintf(landmark, sizeof landmark, "%s/lib/python%d.%d/os.py", folder[0] ? folder : "", major, minor);
        if (is_file(landmark)) {
            const char *home = folder[0] ? folder : "/";
            void (*set_home)(const wchar_t *) = (void (*)(const wchar_t *))dlsym(python, "Py_SetPythonHome");
            if (set_home && mbstowcs(home_w, home, PATH_MAX - 1) != (size_t)-1) {
                home_w[PATH_MAX - 1] = L'\0';
                set_home(home_w);
            } else {
                setenv("PYTHONHOME", home, 0);
            }
            return;
        }
    }
}

/* Make sure the process has CPython; on failure, `why` says what was tried. */
static int ensure_python(const char *resources, char *why, size_t size) {
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized")) return 1;
    char candidates[6][PATH_MAX];
    int n = 0;
    char record[PATH_MAX + 32];
    snprintf(record, sizeof record, "%s/%s", resources, PYTHON_RECORD);
    FILE *file = fopen(record, "r");
    if (file) {
        if (fgets(candidates[n], PATH_MAX, file)) {
            candidates[n][strcspn(candidates[n], "\r\n")] = '\0';
            if (candidates[n][0]) n++;
        }
        fclose(file);
    }
    for (int minor = 13; minor >= 10; minor--) snprintf(candidates[n++], PATH_MAX, "libpython3.%d.so.1.0", minor);
    size_t used = (size_t)snprintf(why, size, "this process has no Python runtime and none could be loaded; tried:");
    for (int i = 0; i < n; i++) {
        void *python = dlopen(candidates[i], RTLD_NOW | RTLD_GLOBAL);
        if (python) {
            set_python_home(python);
            return 1;
        }
        const char *error = dlerror();
        if (used < size) used += (size_t)snprintf(why + used, size - used, " %s (%s);", candidates[i], error ? error : "?");
    }
    if (used < size)
        snprintf(why + used, size - used, " workaround: start the host with LD_PRELOAD=<LIBDIR>/libpython3.X.so "
                 "of a Python 3.10 to 3.13 with a shared libpython");
    return 0;
}
#endif

/* Whether fmuGUID is the guid of <resources>/../modelDescription.xml (not found: not checked). */
static int guid_matches(const char *resources, const char *guid, char *why, size_t size) {
    if (!guid) {
        snprintf(why, size, "fmuGUID is NULL");
        return 0;
    }
    char path[PATH_MAX + 32];
    snprintf(path, sizeof path, "%s/../modelDescription.xml", resources);
    FILE *file = fopen(path, "rb");
    if (!file) return 1;
    static char text[1 << 16]; /* the guid is an attribute of the root element, in the first lines */
    size_t n = fread(text, 1, sizeof text - 1, file);
    fclose(file);
    text[n] = '\0';
    const char *found = strstr(text, " guid=\"");
    if (!found) return 1;
    found += 7;
    const char *end = strchr(found, '"');
    if (!end) return 1;
    size_t length = (size_t)(end - found);
    if (strlen(guid) == length && strncmp(found, guid, length) == 0) return 1;
    snprintf(why, size, "fmuGUID %.200s is not this FMU's guid %.*s (a modelDescription.xml of another FMU?)",
             guid, (int)(length < 200 ? length : 200), found);
    return 0;
}

/* Whether resources holds pythonfmu's slavemodule.txt and the script it names (pythonfmu crashes
   on a folder without them, e.g. a wrong fmuResourceLocation). */
static int resources_ok(const char *resources, char *why, size_t size) {
    char path[PATH_MAX + 64], module[256];
    snprintf(path, sizeof path, "%s/slavemodule.txt", resources);
    FILE *file = fopen(path, "r");
    int ok = file && fgets(module, sizeof module, file);
    if (file) fclose(file);
    if (ok) {
        module[strcspn(module, "\r\n")] = '\0';
        snprintf(path, sizeof path, "%s/%s.py", resources, module);
        ok = module[0] && !strchr(module, '/') && is_file(path);
    }
    if (!ok)
        snprintf(why, size, "fmuResourceLocation %.1000s is not this FMU's resources folder (no slavemodule.txt "
                 "naming a script there)", resources);
    return ok;
}

/* The path of this library (the shim), or 0. */
static int own_path(char *path, size_t size) {
#ifdef _WIN32
    HMODULE self;
    if (!GetModuleHandleExA(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCSTR)(void *)&locate_self, &self))
        return 0;
    DWORD n = GetModuleFileNameA(self, path, (DWORD)size);
    return n > 0 && n < size;
#else
    Dl_info info;
    if (!dladdr((void *)&locate_self, &info) || !info.dli_fname) return 0;
    return snprintf(path, size, "%s", info.dli_fname) < (int)size;
#endif
}

/* Load pythonfmu's binary (next to this one) once; on failure, `why` says why. */
#ifndef _WIN32
/* pythonfmu 0.7.0 (Linux) holds its interpreter state in a global shared_ptr, and releases it twice
   at exit: once by the pointer's static destructor, then again in finalizePythonInterpreter, run
   from the library's fini with the pointer still naming the freed block. That second release
   writes into freed memory: a host that created an instance may abort at exit ("corrupted
   double-linked list", 1 host run in a few hundred; valgrind shows the use after free in every
   run). Calling finalizePythonInterpreter first, from an exit handler registered after the
   library's own (handlers run in reverse), releases the state once while everything is alive and
   leaves the pointer empty, so that both later releases do nothing. Registered from this shared
   object, the handler also runs if the host unloads it before exiting. */
static void (*release_python_state)(void);
static void release_state(void) {
    if (release_python_state) release_python_state();
}
static void release_at_exit(void *library) {
    release_python_state = (void (*)(void))find(library, "finalizePythonInterpreter");
    if (release_python_state) atexit(release_state);
}
#endif

static int load_inner(char *why, size_t size) {
    if (inner_library) return 1;
    char path[PATH_MAX + 32];
    if (!own_path(path, sizeof path - sizeof INNER_SUFFIX)) {
        snprintf(why, size, "cannot find the path of the FMU's binary");
        return 0;
    }
    size_t n = strlen(path), own = strlen(OWN_SUFFIX);
    if (n > own && strcmp(path + n - own, OWN_SUFFIX) == 0) path[n - own] = '\0';
    strncat(path, INNER_SUFFIX, sizeof path - strlen(path) - 1);
    void *library = open_inner(path);
    if (!library) {
        snprintf(why, size, "cannot load %s: %s", path, load_error());
        return 0;
    }
#define LOOKUP(name) inner.name = (name##TYPE *)find(library, #name);
    INNER_FUNCTIONS(LOOKUP)
#undef LOOKUP
    if (!inner.fmi2Instantiate || !inner.fmi2FreeInstance) {
        snprintf(why, size, "%s exports no fmi2Instantiate/fmi2FreeInstance", path);
        return 0;
    }
    inner_library = library; /* never closed: pythonfmu's interpreter thread lives in it */
#ifndef _WIN32
    release_at_exit(library);
#endif
    return 1;
}

/* Length of the UTF-8 character at p[0] (n bytes left), 0 if the bytes there are not valid UTF-8. */
static size_t utf8_char(const unsigned char *p, size_t n) {
    unsigned char c = p[0];
    size_t len = c < 0x80 ? 1 : (c >= 0xC2 && c <= 0xDF) ? 2 : (c >= 0xE0 && c <= 0xEF) ? 3
               : (c >= 0xF0 && c <= 0xF4) ? 4 : 0;
    if (len == 0 || len > n) return 0;
    for (size_t k = 1; k < len; k++)
        if ((p[k] & 0xC0) != 0x80) return 0;
    if (len == 3 && ((c == 0xE0 && p[1] < 0xA0) || (c == 0xED && p[1] > 0x9F))) return 0; /* overlong, surrogate */
    if (len == 4 && ((c == 0xF0 && p[1] < 0x90) || (c == 0xF4 && p[1] > 0x8F))) return 0; /* overlong, > U+10FFFF */
    return len;
}

/* Whether text is valid UTF-8 (pythonfmu makes Python strs of strings and fails fatally, or crashes, on
   anything else). */
static int utf8_valid(const char *text) {
    const unsigned char *p = (const unsigned char *)text;
    size_t n = strlen(text);
    for (size_t i = 0, len; i < n; i += len)
        if (!(len = utf8_char(p + i, n - i))) return 0;
    return 1;
}

/* A copy of text with every byte that is not part of valid UTF-8 replaced by '?' (NULL: ""). */
static char *utf8_copy(const char *text) {
    const unsigned char *p = (const unsigned char *)(text ? text : "");
    size_t n = strlen((const char *)p);
    char *out = malloc(n + 1);
    if (!out) return NULL;
    for (size_t i = 0, len; i < n; i += len) {
        len = utf8_char(p + i, n - i);
        if (len) {
            memcpy(out + i, p + i, len);
        } else {
            out[i] = '?';
            len = 1;
        }
    }
    out[n] = '\0';
    return out;
}

/* ------------------------------------------------------------------ FMI 2.0 */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Shim *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    if (functions) s->host = *functions;
    s->name = utf8_copy(instanceName);
    if (!s->name) {
        free(s);
        return NULL;
    }
    s->logging_on = loggingOn != fmi2False;
    s->own.logger = inner_logger;
    s->own.allocateMemory = s->host.allocateMemory ? s->host.allocateMemory : calloc;
    s->own.freeMemory = s->host.freeMemory ? s->host.freeMemory : free;
    s->own.stepFinished = NULL;
    s->own.componentEnvironment = s;

    char why[4096], resources[PATH_MAX];
    int ok;
    lock();
    if (fmuType != fmi2CoSimulation) {
        snprintf(why, sizeof why, "fmuType %d refused: this FMU is for co-simulation (fmi2CoSimulation) only",
                 (int)fmuType);
        ok = 0;
    } else if (!resource_folder(fmuResourceLocation, resources, sizeof resources)) {
        snprintf(why, sizeof why, "fmuResourceLocation %.1000s is not a file: URI",
                 fmuResourceLocation ? fmuResourceLocation : "(NULL)");
        ok = 0;
    } else if (!resources_ok(resources, why, sizeof why) || !guid_matches(resources, fmuGUID, why, sizeof why)) {
        ok = 0;
    } else {
        ok = ensure_python(resources, why, sizeof why) && load_inner(why, sizeof why);
    }
    unlock();
    if (!ok) {
        shim_log(s, fmi2Fatal, "fmi2Instantiate: %s", why);
        free(s->name);
        free(s);
        return NULL;
    }
    BEGIN(s);
    /* pythonfmu takes the URI minus "file://" (on Windows "file:///"), with only %20 decoded: give it the
       decoded folder */
#ifdef _WIN32
    const char *scheme = "file:///";
#else
    const char *scheme = "file://";
#endif
    char *uri = malloc(strlen(resources) + 9);
    if (!uri) {
        free(s->name);
        free(s);
        return NULL;
    }
    strcpy(uri, scheme);
    strcat(uri, resources);
    s->inner = inner.fmi2Instantiate(s->name, fmuType, fmuGUID, uri, &s->own, visible, fmi2True);
    free(uri);
    if (!s->inner) {
        free(s->name);
        free(s);
        return NULL;
    }
    s->phase = INSTANTIATED;
    return s;
}

void fmi2FreeInstance(fmi2Component c) {
    Shim *s = (Shim *)c;
    if (!s) return;
    if (!s->fatal && s->inner) {
        BEGIN(s);
        inner.fmi2FreeInstance(s->inner);
    } /* else: leaked on purpose (pythonfmu released its objects at the fatal error) */
    free(s->name);
    free(s);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    Shim *s = (Shim *)c;
    if (!s) return fmi2Error;
    s->logging_on = loggingOn != fmi2False; /* pythonfmu's own logging stays on, unfiltered */
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    FORWARD(c, fmi2SetupExperiment, NORMAL, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime)
    return status;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2EnterInitializationMode", NORMAL, &refused)) return refused;
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2EnterInitializationMode", inner.fmi2EnterInitializationMode(s->inner));
    if (status <= fmi2Warning) s->phase = INITIALIZING;
    return status;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2ExitInitializationMode", NORMAL, &refused)) return refused;
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2ExitInitializationMode", inner.fmi2ExitInitializationMode(s->inner));
    if (status <= fmi2Warning) s->phase = STEPPING;
    return status;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2Terminate", NORMAL, &refused)) return refused;
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2Terminate", inner.fmi2Terminate(s->inner));
    if (status <= fmi2Warning) s->phase = TERMINATED;
    return status;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2Reset", ANYTIME, &refused)) return refused; /* refused only after fmi2Fatal */
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2Reset", inner.fmi2Reset(s->inner));
    if (status <= fmi2Warning) {
        s->error = 0;
        s->phase = INSTANTIATED;
    }
    return status;
}

/* A NULL array with nvr > 0 (pythonfmu would read or write through it). */
#define CHECK_ARRAYS(c, function, vr, nvr, value)                                                  \
    if ((c) && (nvr) > 0 && (!(vr) || !(value)) && !((Shim *)(c))->fatal)                        \
        return refuse((Shim *)(c), #function, "a NULL valueReference or value array with nvr > 0");

#define GETTER(function, type)                                                                    \
    fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, type value[]) { \
        CHECK_ARRAYS(c, function, vr, nvr, value)                                                 \
        FORWARD(c, function, ANYTIME, vr, nvr, value)                                             \
        return status;                                                                            \
    }
GETTER(fmi2GetReal, fmi2Real)
GETTER(fmi2GetInteger, fmi2Integer)
GETTER(fmi2GetBoolean, fmi2Boolean)
GETTER(fmi2GetString, fmi2String)

#define SETTER(function, type)                                                                          \
    fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const type value[]) { \
        CHECK_ARRAYS(c, function, vr, nvr, value)                                                       \
        FORWARD(c, function, NORMAL, vr, nvr, value)                                                    \
        return status;                                                                                  \
    }
SETTER(fmi2SetReal, fmi2Real)
SETTER(fmi2SetInteger, fmi2Integer)
SETTER(fmi2SetBoolean, fmi2Boolean)

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    CHECK_ARRAYS(c, fmi2SetString, vr, nvr, value)
    if (c && !((Shim *)c)->fatal)
        for (size_t i = 0; i < nvr; i++)
            if (!value[i] || !utf8_valid(value[i]))
                return refuse((Shim *)c, "fmi2SetString", "a value that is NULL or not UTF-8 text");
    FORWARD(c, fmi2SetString, NORMAL, vr, nvr, value)
    return status;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (c && !FMUstate && !((Shim *)c)->fatal) return refuse((Shim *)c, "fmi2GetFMUstate", "FMUstate is NULL");
    FORWARD(c, fmi2GetFMUstate, ANYTIME, FMUstate)
    return status;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2SetFMUstate", ANYTIME, &refused)) return refused;
    if (!FMUstate) return refuse(s, "fmi2SetFMUstate", "FMUstate is NULL");
    s->error = 0; /* a restored state leaves the Error state; settle() re-enters it if this fails */
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2SetFMUstate", inner.fmi2SetFMUstate(s->inner, FMUstate));
    if (status == fmi2OK || status == fmi2Warning) {
        /* The restored state carries its own phase of the call sequence (an instance that was never
           initialised may take a state saved mid-run): ask the facade, at its private value
           reference PHASE_VR (fmus/facade.py), and follow it. */
        const fmi2ValueReference phase_vr = PHASE_VR;
        fmi2Integer phase = -1;
        BEGIN(s);
        if (settle(s, "fmi2SetFMUstate", inner.fmi2GetInteger(s->inner, &phase_vr, 1, &phase)) != fmi2OK) return fmi2Error;
        switch (phase) {
        case 0: s->phase = INSTANTIATED; break;
        case 1: s->phase = INITIALIZING; break;
        case 2: s->phase = STEPPING; break;
        case 3: s->phase = TERMINATED; break;
        default:
            shim_log(s, fmi2Error, "fmi2SetFMUstate: the restored state has no valid phase (%d)", (int)phase);
            s->error = 1;
            return fmi2Error;
        }
    }
    return status;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2FreeFMUstate", ANYTIME, &refused)) return refused;
    if (!FMUstate) return refuse(s, "fmi2FreeFMUstate", "the pointer to the FMUstate is NULL");
    if (!*FMUstate) return fmi2OK; /* the standard: a NULL state is ignored */
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2FreeFMUstate", inner.fmi2FreeFMUstate(s->inner, FMUstate));
    if (status <= fmi2Warning) *FMUstate = NULL; /* freed: a second free is harmless */
    return status;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    if (c && (!FMUstate || !size) && !((Shim *)c)->fatal)
        return refuse((Shim *)c, "fmi2SerializedFMUstateSize", "FMUstate or size is NULL");
    FORWARD(c, fmi2SerializedFMUstateSize, ANYTIME, FMUstate, size)
    return status;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2SerializeFMUstate", ANYTIME, &refused)) return refused;
    if (!FMUstate || !serializedState) return refuse(s, "fmi2SerializeFMUstate", "FMUstate or the buffer is NULL");
    size_t needed = 0;
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2SerializeFMUstate", inner.fmi2SerializedFMUstateSize(s->inner, FMUstate, &needed));
    if (status > fmi2Warning) return status;
    if (size < needed) {
        shim_log(s, fmi2Error, "fmi2SerializeFMUstate: a buffer of %zu bytes, but the state needs %zu "
                 "(fmi2SerializedFMUstateSize)", size, needed);
        s->error = 1;
        return fmi2Error;
    }
    fmi2Byte *exact = malloc(needed ? needed : 1); /* pythonfmu copies exactly the size it is given */
    if (!exact) return refuse(s, "fmi2SerializeFMUstate", "out of memory");
    BEGIN(s);
    status = settle(s, "fmi2SerializeFMUstate", inner.fmi2SerializeFMUstate(s->inner, FMUstate, exact, needed));
    if (status <= fmi2Warning) memcpy(serializedState, exact, needed);
    free(exact);
    return status;
}

/* pythonfmu deserializes by a class method with no instance to log to: bytes the facade refuses become a
   RefusedState, which it serializes as REFUSED_PREFIX + the reason (fmus/facade.py _fmu_state_to_bytes).
   1 (and the reason in why) if the state just deserialized is such a refusal. */
#define REFUSED_PREFIX "dfwb-fmu-state\nrefused: "
static int refused_state(Shim *s, fmi2FMUstate state, char *why, size_t room) {
    size_t size = 0, prefix = sizeof REFUSED_PREFIX - 1;
    char *bytes = NULL;
    int refused = 1;
    snprintf(why, room, "the state read cannot be serialized again");
    BEGIN(s);
    if (settle(s, "fmi2SerializedFMUstateSize", inner.fmi2SerializedFMUstateSize(s->inner, state, &size)) <=
            fmi2Warning && size <= MAX_STATE_BYTES && (bytes = malloc(size ? size : 1))) {
        BEGIN(s);
        if (settle(s, "fmi2SerializeFMUstate", inner.fmi2SerializeFMUstate(s->inner, state, bytes, size)) <=
                fmi2Warning) {
            refused = size >= prefix && memcmp(bytes, REFUSED_PREFIX, prefix) == 0;
            if (refused) snprintf(why, room, "%.*s", (int)(size - prefix), bytes + prefix);
        }
    }
    free(bytes);
    return refused;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2DeSerializeFMUstate", ANYTIME, &refused)) return refused;
    if (!FMUstate || (!serializedState && size > 0))
        return refuse(s, "fmi2DeSerializeFMUstate", "the bytes or the pointer to the FMUstate is NULL");
    if (size > MAX_STATE_BYTES) {
        shim_log(s, fmi2Error, "fmi2DeSerializeFMUstate: %zu bytes refused: a serialized state of this FMU "
                 "is at most %zu bytes", size, MAX_STATE_BYTES);
        s->error = 1;
        return fmi2Error;
    }
    fmi2FMUstate fresh = NULL; /* the host's *FMUstate is replaced only by a state that was accepted */
    BEGIN(s);
    fmi2Status status = settle(s, "fmi2DeSerializeFMUstate",
                               inner.fmi2DeSerializeFMUstate(s->inner, serializedState ? serializedState : "",
                                                             size, &fresh));
    if (status > fmi2Warning) return status;
    char why[1024];
    if (refused_state(s, fresh, why, sizeof why)) {
        BEGIN(s);
        settle(s, "fmi2FreeFMUstate", inner.fmi2FreeFMUstate(s->inner, &fresh));
        shim_log(s, fmi2Error, "fmi2DeSerializeFMUstate: %s", why);
        s->error = 1;
        return fmi2Error;
    }
    if (*FMUstate) {
        BEGIN(s);
        settle(s, "fmi2FreeFMUstate", inner.fmi2FreeFMUstate(s->inner, FMUstate));
    }
    *FMUstate = fresh;
    return status;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    FORWARD(c, fmi2GetDirectionalDerivative, ANYTIME, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
            dvUnknown)
    return status;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    FORWARD(c, fmi2SetRealInputDerivatives, NORMAL, vr, nvr, order, value)
    return status;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    FORWARD(c, fmi2GetRealOutputDerivatives, ANYTIME, vr, nvr, order, value)
    return status;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2DoStep", NORMAL, &refused)) return refused;
    if (s->phase != STEPPING) {
        shim_log(s, fmi2Error, "fmi2DoStep: called before fmi2ExitInitializationMode");
        s->error = 1;
        return fmi2Error;
    }
    BEGIN(s);
    return settle(s, "fmi2DoStep",
                  inner.fmi2DoStep(s->inner, currentCommunicationPoint, communicationStepSize,
                                   noSetFMUStatePriorToCurrentPoint));
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Shim *s = (Shim *)c;
    fmi2Status refused = fmi2Error;
    if (!s) return fmi2Error;
    if (!admit(s, "fmi2CancelStep", NORMAL, &refused)) return refused;
    BEGIN(s);
    return settle(s, "fmi2CancelStep", inner.fmi2CancelStep(s->inner));
}

#define STATUS_GETTER(function, type)                                                   \
    fmi2Status function(fmi2Component c, const fmi2StatusKind kind, type *value) {      \
        if (c && !value && !((Shim *)c)->fatal) return refuse((Shim *)c, #function, "value is NULL"); \
        FORWARD(c, function, ANYTIME, kind, value)                                      \
        return status;                                                                  \
    }
STATUS_GETTER(fmi2GetStatus, fmi2Status)
STATUS_GETTER(fmi2GetRealStatus, fmi2Real)
STATUS_GETTER(fmi2GetIntegerStatus, fmi2Integer)
STATUS_GETTER(fmi2GetBooleanStatus, fmi2Boolean)
STATUS_GETTER(fmi2GetStringStatus, fmi2String)
