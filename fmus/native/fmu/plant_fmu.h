/* plant_fmu.h - one dfwb plant as an FMU instance, whatever the FMI version: the state machine, variables,
   refusals and FMU states of plant_fmu.c, under the thin FMI 2.0 (fmi2_plant.c) and FMI 3.0 (fmi3_plant.c)
   layers. Statuses are FMI's (OK 0, Warning 1, Discard 2, Error 3, Fatal 4: the same in both versions);
   values travel as doubles (an Integer variable's too), value references index dfwb_model.h's table. */
#ifndef DFWB_PLANT_FMU_H
#define DFWB_PLANT_FMU_H

#include <stddef.h>

#if defined(_WIN32)
#define FMI_API __declspec(dllexport)
#else
#define FMI_API __attribute__((visibility("default")))
#endif

enum { PLANT_OK = 0, PLANT_WARNING = 1, PLANT_DISCARD = 2, PLANT_ERROR = 3, PLANT_FATAL = 4 };

typedef unsigned int plant_vr; /* fmi2ValueReference and fmi3ValueReference alike */

/* What the FMI layer gives an instance: its logger (a finished message, never a format) and memory. */
typedef struct plant_host {
    void (*log)(const struct plant_host *host, const char *instance, int status, const char *category,
                const char *message);
    void *environment;    /* the importer's (componentEnvironment, instanceEnvironment) */
    void (*callback)(void); /* the importer's logger, as the FMI layer's log() casts it back */
    void *(*allocate)(size_t count, size_t size);
    void (*release)(void *memory);
    const char *real_kind, *integer_kind; /* the types' names in messages: "Real", "Integer" (FMI 2.0) */
} plant_host;

typedef struct plant_fmu plant_fmu;

const char *plant_fmu_model(void); /* the model's name */
const char *plant_fmu_token(void); /* its GUID (FMI 2.0), its instantiationToken (FMI 3.0) */
plant_fmu *plant_fmu_new(const char *name, int logging, const plant_host *host);
void plant_fmu_free(plant_fmu *c);
const char *plant_fmu_name(const plant_fmu *c);
void plant_fmu_logging(plant_fmu *c, int on);
int plant_fmu_refuse(plant_fmu *c, const char *fmt, ...)
#if defined(__MINGW32__)
    __attribute__((format(gnu_printf, 2, 3)))
#elif defined(__GNUC__) || defined(__clang__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

int plant_fmu_reset(plant_fmu *c);
int plant_fmu_setup(plant_fmu *c, double start_time);
int plant_fmu_enter_initialization(plant_fmu *c);
int plant_fmu_exit_initialization(plant_fmu *c);
int plant_fmu_step(plant_fmu *c, double t, double h);
int plant_fmu_terminate(plant_fmu *c);
double plant_fmu_time(const plant_fmu *c);

/* Getters and setters of one kind (integer: Integer/Int32 variables, else Real/Float64); `call` names the
   FMI function in messages. Integers are fetched as int32 (a larger value is refused). */
int plant_fmu_get_reals(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, double value[]);
int plant_fmu_get_integers(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, int value[]);
int plant_fmu_set_reals(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, const double value[]);
int plant_fmu_set_integers(plant_fmu *c, const char *call, const plant_vr vr[], size_t n, const int value[]);
int plant_fmu_no_variable(plant_fmu *c, const plant_vr vr[], size_t n, const char *kind);

/* FMU states: handles of this model only (a tag marks them), serialized as checked bytes. */
int plant_fmu_get_state(plant_fmu *c, void **state);
int plant_fmu_set_state(plant_fmu *c, void *state);
int plant_fmu_free_state(plant_fmu *c, void **state);
int plant_fmu_state_size(plant_fmu *c, void *state, size_t *size);
int plant_fmu_serialize(plant_fmu *c, void *state, unsigned char out[], size_t size);
int plant_fmu_deserialize(plant_fmu *c, const unsigned char in[], size_t size, void **state);

#endif
