/* fmi2_plant.c - the FMI 2.0 co-simulation interface of a native dfwb plant FMU: each fmi2 function checks
   what only FMI 2.0 has (the fmuType, the GUID, the callbacks) and calls plant_fmu.c, which holds the
   behaviour (see its comment). Messages go to the host's logger with every '%' doubled (it reads a printf
   format); memory comes from its allocateMemory/freeMemory. */

#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "plant_fmu.h"

#define MESSAGE 1200

static void log_fmi2(const plant_host *host, const char *instance, int status, const char *category,
                     const char *text)
{
    fmi2CallbackLogger logger = (fmi2CallbackLogger)host->callback;
    char escaped[2 * MESSAGE + 1], *out = escaped;
    const char *p;
    if (!logger) return;
    for (p = text; *p && out < escaped + 2 * MESSAGE - 1; p++) { /* the host's logger reads a printf format */
        *out++ = *p;
        if (*p == '%') *out++ = '%';
    }
    *out = '\0';
    logger(host->environment, instance, (fmi2Status)status, category, escaped);
}

FMI_API const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI_API const char *fmi2GetVersion(void) { return fmi2Version; }

FMI_API fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                      const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                      fmi2Boolean loggingOn)
{
    plant_host host;
    char why[200];
    (void)resources;
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (type != fmi2CoSimulation || !guid || strcmp(guid, plant_fmu_token()) != 0) {
        snprintf(why, sizeof why, "%s: %s", plant_fmu_model(),
                 type != fmi2CoSimulation ? "only co-simulation is supported" : "the GUID is not this FMU's");
        if (functions->logger)
            functions->logger(functions->componentEnvironment, name ? name : "", fmi2Fatal, "logStatusFatal", why);
        return NULL;
    }
    host.log = log_fmi2;
    host.environment = functions->componentEnvironment;
    host.callback = (void (*)(void))functions->logger;
    host.allocate = functions->allocateMemory;
    host.release = functions->freeMemory;
    host.real_kind = "Real";
    host.integer_kind = "Integer";
    return plant_fmu_new(name, loggingOn != fmi2False, &host);
}

FMI_API void fmi2FreeInstance(fmi2Component c) { plant_fmu_free(c); }

FMI_API fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[])
{
    (void)n;
    (void)categories;
    if (!c) return fmi2Error;
    plant_fmu_logging(c, loggingOn != fmi2False);
    return fmi2OK;
}

/* Every other call: fmi2Error for a NULL instance, else plant_fmu's status. */
#define CALL(c, expression) ((c) ? (fmi2Status)(expression) : fmi2Error)

FMI_API fmi2Status fmi2Reset(fmi2Component c) { return CALL(c, plant_fmu_reset(c)); }

FMI_API fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                       fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    return CALL(c, plant_fmu_setup(c, startTime));
}

FMI_API fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return CALL(c, plant_fmu_enter_initialization(c)); }
FMI_API fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return CALL(c, plant_fmu_exit_initialization(c)); }

FMI_API fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    (void)noSetPrior;
    return CALL(c, plant_fmu_step(c, t, h));
}

FMI_API fmi2Status fmi2CancelStep(fmi2Component c)
{
    return CALL(c, plant_fmu_refuse(c, "cancelStep refused: doStep never returns fmi2Pending"));
}

FMI_API fmi2Status fmi2Terminate(fmi2Component c) { return CALL(c, plant_fmu_terminate(c)); }

FMI_API fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    return CALL(c, plant_fmu_get_reals(c, "getReal", vr, n, value));
}

FMI_API fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[])
{
    return CALL(c, plant_fmu_get_integers(c, "getInteger", vr, n, value));
}

FMI_API fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[])
{
    if (!c) return fmi2Error;
    if (n == 0) return fmi2OK;
    if (value) memset(value, 0, n * sizeof value[0]);
    return (fmi2Status)plant_fmu_refuse(
        c, "getBoolean failed: TypeError: Variable with valueReference=%u is not of type Boolean!",
        vr ? (unsigned)vr[0] : 0u);
}

FMI_API fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[])
{
    size_t i;
    if (!c) return fmi2Error;
    if (n == 0) return fmi2OK;
    for (i = 0; value && i < n; i++) value[i] = "";
    return (fmi2Status)plant_fmu_refuse(
        c, "getString failed: TypeError: Variable with valueReference=%u is not of type String!",
        vr ? (unsigned)vr[0] : 0u);
}

FMI_API fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    return CALL(c, plant_fmu_set_reals(c, "setReal", vr, n, value));
}

FMI_API fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                  const fmi2Integer value[])
{
    return CALL(c, plant_fmu_set_integers(c, "setInteger", vr, n, value));
}

FMI_API fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{
    (void)v;
    return CALL(c, plant_fmu_no_variable(c, vr, n, "Boolean"));
}

FMI_API fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{
    (void)v;
    return CALL(c, plant_fmu_no_variable(c, vr, n, "String"));
}

FMI_API fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    return CALL(c, plant_fmu_get_state(c, state));
}

FMI_API fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) { return CALL(c, plant_fmu_set_state(c, state)); }

FMI_API fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    return CALL(c, plant_fmu_free_state(c, state));
}

FMI_API fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    return CALL(c, plant_fmu_state_size(c, state, size));
}

FMI_API fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size)
{
    return CALL(c, plant_fmu_serialize(c, state, (unsigned char *)out, size));
}

FMI_API fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate *state)
{
    return CALL(c, plant_fmu_deserialize(c, (const unsigned char *)in, size, state));
}

/* -- what a co-simulation FMU without derivatives or asynchronous steps answers ------------------- */
FMI_API fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                                const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                                fmi2Real dz[])
{
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    return CALL(c, plant_fmu_refuse(c, "getDirectionalDerivative refused: providesDirectionalDerivative is false"));
}

FMI_API fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                               const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return CALL(c, plant_fmu_refuse(c, "setRealInputDerivatives refused: canInterpolateInputs is false"));
}

FMI_API fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                                const fmi2Integer order[], fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return CALL(c, plant_fmu_refuse(c, "getRealOutputDerivatives refused: maxOutputDerivativeOrder is 0"));
}

/* The step status functions only make sense after fmi2Pending or fmi2Discard, which doStep never returns. */
FMI_API fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    if (!c || !value) return fmi2Error;
    *value = fmi2OK;
    return fmi2Discard;
}

FMI_API fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    if (!c || !value) return fmi2Error;
    *value = plant_fmu_time(c); /* fmi2LastSuccessfulTime */
    return s == fmi2LastSuccessfulTime ? fmi2OK : fmi2Discard;
}

FMI_API fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s;
    if (!c || !value) return fmi2Error;
    *value = 0;
    return fmi2Discard;
}

FMI_API fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    if (!c || !value) return fmi2Error;
    *value = fmi2False; /* fmi2Terminated: the FMU never asks to stop */
    return s == fmi2Terminated ? fmi2OK : fmi2Discard;
}

FMI_API fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s;
    if (!c || !value) return fmi2Error;
    *value = "";
    return fmi2Discard;
}
