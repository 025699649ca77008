/* fmi3_plant.c - the FMI 3.0 co-simulation interface of a native dfwb plant FMU, over plant_fmu.c (the same
   instance, variables, numbers, refusals and FMU states as the FMI 2.0 FMU; see plant_fmu.c's comment).

   What FMI 3.0 changes for these plants:
   - Variables are Float64 (the FMI 2.0 Reals) and Int32 (the Integers), all scalars, plus the independent
     variable `time` (the last value reference); the getters and setters check nValues = nValueReferences.
   - fmi3EnterInitializationMode takes the start time (FMI 2.0's fmi2SetupExperiment).
   - fmi3DoStep reports no event, no early return and no end of simulation: the exact solver steps across
     every stick, break-away and impact inside the step (hasEventMode is false, so the importer never asks for
     Event Mode; an instantiation with eventModeUsed, or with required intermediate variables, is refused).
   - Messages go to logMessage as they are (no printf format in FMI 3.0); memory is calloc/free.
   - Model exchange and scheduled execution are not provided: their instantiation returns NULL with a message.
   Every function FMI 3.0 defines for co-simulation is exported; those the FMU does not support (clocks,
   configuration mode, derivatives, dependencies, event mode) log why and return fmi3Error. */

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "plant_fmu.h"

static void log_fmi3(const plant_host *host, const char *instance, int status, const char *category,
                     const char *text)
{
    fmi3LogMessageCallback logger = (fmi3LogMessageCallback)host->callback;
    (void)instance;
    if (logger) logger(host->environment, (fmi3Status)status, category, text);
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

static fmi3Instance refused_instance(fmi3InstanceEnvironment environment, fmi3LogMessageCallback logMessage,
                                     const char *why)
{
    char text[300];
    snprintf(text, sizeof text, "%s: %s", plant_fmu_model(), why);
    if (logMessage) logMessage(environment, fmi3Fatal, "logStatusFatal", text);
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[], size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate)
{
    plant_host host;
    (void)resourcePath, (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    if (!instantiationToken || strcmp(instantiationToken, plant_fmu_token()) != 0)
        return refused_instance(instanceEnvironment, logMessage, "the instantiationToken is not this FMU's");
    if (eventModeUsed)
        return refused_instance(instanceEnvironment, logMessage,
                                "eventModeUsed refused: the FMU has no Event Mode (hasEventMode is false)");
    if (nRequiredIntermediateVariables)
        return refused_instance(instanceEnvironment, logMessage,
                                "requiredIntermediateVariables refused: the FMU has no intermediate variables");
    host.log = log_fmi3;
    host.environment = instanceEnvironment;
    host.callback = (void (*)(void))logMessage;
    host.allocate = calloc;
    host.release = free;
    host.real_kind = "Float64";
    host.integer_kind = "Int32";
    return plant_fmu_new(instanceName, loggingOn != fmi3False, &host);
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                      fmi3String resourcePath, fmi3Boolean visible,
                                                      fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                                      fmi3LogMessageCallback logMessage)
{
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    return refused_instance(instanceEnvironment, logMessage, "only co-simulation is supported");
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    return refused_instance(instanceEnvironment, logMessage, "only co-simulation is supported");
}

FMI3_Export void fmi3FreeInstance(fmi3Instance c) { plant_fmu_free(c); }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t n,
                                           const fmi3String categories[])
{
    (void)n, (void)categories;
    if (!c) return fmi3Error;
    plant_fmu_logging(c, loggingOn != fmi3False);
    return fmi3OK;
}

/* Every other call: fmi3Error for a NULL instance, else plant_fmu's status. */
#define CALL(c, expression) ((c) ? (fmi3Status)(expression) : fmi3Error)
#define REFUSE(c, why) CALL(c, plant_fmu_refuse(c, "%s refused: %s", __func__, why))

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                                   fmi3Float64 startTime, fmi3Boolean stopTimeDefined,
                                                   fmi3Float64 stopTime)
{
    int status;
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    if (!c) return fmi3Error;
    status = plant_fmu_setup(c, startTime);
    return (fmi3Status)(status == PLANT_OK ? plant_fmu_enter_initialization(c) : status);
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance c) { return CALL(c, plant_fmu_exit_initialization(c)); }
FMI3_Export fmi3Status fmi3Terminate(fmi3Instance c) { return CALL(c, plant_fmu_terminate(c)); }
FMI3_Export fmi3Status fmi3Reset(fmi3Instance c) { return CALL(c, plant_fmu_reset(c)); }

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                  fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    fmi3Status status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c) return fmi3Error;
    status = (fmi3Status)plant_fmu_step(c, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = plant_fmu_time(c);
    return status;
}

/* -- variables: Float64 and Int32 scalars ------------------------------------------------------------- */
static int scalars(fmi3Instance c, const char *call, size_t nvr, size_t nValues)
{
    if (nValues == nvr) return 1;
    plant_fmu_refuse(c, "%s: %zu values for %zu valueReferences (every variable is a scalar)", call, nValues, nvr);
    return 0;
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                                      size_t nValues)
{
    if (!c) return fmi3Error;
    if (!scalars(c, "getFloat64", nvr, nValues)) return fmi3Error;
    return (fmi3Status)plant_fmu_get_reals(c, "getFloat64", vr, nvr, values);
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                                    size_t nValues)
{
    if (!c) return fmi3Error;
    if (!scalars(c, "getInt32", nvr, nValues)) return fmi3Error;
    return (fmi3Status)plant_fmu_get_integers(c, "getInt32", vr, nvr, values);
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                      const fmi3Float64 values[], size_t nValues)
{
    if (!c) return fmi3Error;
    if (!scalars(c, "setFloat64", nvr, nValues)) return fmi3Error;
    return (fmi3Status)plant_fmu_set_reals(c, "setFloat64", vr, nvr, values);
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 values[], size_t nValues)
{
    if (!c) return fmi3Error;
    if (!scalars(c, "setInt32", nvr, nValues)) return fmi3Error;
    return (fmi3Status)plant_fmu_set_integers(c, "setInt32", vr, nvr, values);
}

/* The types this FMU has no variable of: any valueReference is refused, an empty call is fmi3OK. */
#define NO_VARIABLE(Kind, type, qualifier)                                                                 \
    FMI3_Export fmi3Status fmi3Get##Kind(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,        \
                                         type values[], size_t nValues)                                    \
    {                                                                                                      \
        (void)values, (void)nValues;                                                                       \
        return CALL(c, plant_fmu_no_variable(c, vr, nvr, #Kind));                                          \
    }                                                                                                      \
    FMI3_Export fmi3Status fmi3Set##Kind(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,        \
                                         qualifier type values[], size_t nValues)                          \
    {                                                                                                      \
        (void)values, (void)nValues;                                                                       \
        return CALL(c, plant_fmu_no_variable(c, vr, nvr, #Kind));                                          \
    }

NO_VARIABLE(Float32, fmi3Float32, const)
NO_VARIABLE(Int8, fmi3Int8, const)
NO_VARIABLE(UInt8, fmi3UInt8, const)
NO_VARIABLE(Int16, fmi3Int16, const)
NO_VARIABLE(UInt16, fmi3UInt16, const)
NO_VARIABLE(UInt32, fmi3UInt32, const)
NO_VARIABLE(Int64, fmi3Int64, const)
NO_VARIABLE(UInt64, fmi3UInt64, const)
NO_VARIABLE(Boolean, fmi3Boolean, const)
NO_VARIABLE(String, fmi3String, const)

FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                                     fmi3Binary values[], size_t nValues)
{
    (void)valueSizes, (void)values, (void)nValues;
    return CALL(c, plant_fmu_no_variable(c, vr, nvr, "Binary"));
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                     const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueSizes, (void)values, (void)nValues;
    return CALL(c, plant_fmu_no_variable(c, vr, nvr, "Binary"));
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[])
{
    (void)values;
    return CALL(c, plant_fmu_no_variable(c, vr, nvr, "Clock"));
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Clock values[])
{
    (void)values;
    return CALL(c, plant_fmu_no_variable(c, vr, nvr, "Clock"));
}

/* -- FMU state ------------------------------------------------------------------------------------------ */
FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) { return CALL(c, plant_fmu_get_state(c, state)); }
FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) { return CALL(c, plant_fmu_set_state(c, state)); }
FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) { return CALL(c, plant_fmu_free_state(c, state)); }

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size)
{
    return CALL(c, plant_fmu_state_size(c, state, size));
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte out[], size_t size)
{
    return CALL(c, plant_fmu_serialize(c, state, out, size));
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte in[], size_t size, fmi3FMUState *state)
{
    return CALL(c, plant_fmu_deserialize(c, in, size, state));
}

/* -- what this FMU does not provide ---------------------------------------------------------------------- */
FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n)
{
    (void)vr, (void)n;
    return REFUSE(c, "the model description lists the dependencies (ModelStructure)");
}

FMI3_Export fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                                   size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                                   size_t elementIndicesOfIndependents[],
                                                   fmi3DependencyKind dependencyKinds[], size_t nDependencies)
{
    (void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents;
    (void)dependencyKinds, (void)nDependencies;
    return REFUSE(c, "the model description lists the dependencies (ModelStructure)");
}

#define DERIVATIVE(name)                                                                                   \
    FMI3_Export fmi3Status name(fmi3Instance c, const fmi3ValueReference unknowns[], size_t nUnknowns,    \
                                const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], \
                                size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)              \
    {                                                                                                      \
        (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed;            \
        (void)sensitivity, (void)nSensitivity;                                                             \
        return REFUSE(c, "providesDirectionalDerivatives and providesAdjointDerivatives are false");       \
    }
DERIVATIVE(fmi3GetDirectionalDerivative)
DERIVATIVE(fmi3GetAdjointDerivative)

FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                                const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
{
    (void)vr, (void)nvr, (void)orders, (void)values, (void)nValues;
    return REFUSE(c, "maxOutputDerivativeOrder is 0");
}

#define NO_EVENT_MODE "the FMU has no Event Mode (hasEventMode is false)"
FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance c) { return REFUSE(c, NO_EVENT_MODE); }
FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance c) { return REFUSE(c, NO_EVENT_MODE); }
FMI3_Export fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { return REFUSE(c, NO_EVENT_MODE); }

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *discreteStatesNeedUpdate,
                                                fmi3Boolean *terminateSimulation,
                                                fmi3Boolean *nominalsOfContinuousStatesChanged,
                                                fmi3Boolean *valuesOfContinuousStatesChanged,
                                                fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    (void)discreteStatesNeedUpdate, (void)terminateSimulation, (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged, (void)nextEventTimeDefined, (void)nextEventTime;
    return REFUSE(c, NO_EVENT_MODE);
}

#define NO_CONFIGURATION "the FMU has no structural parameters"
FMI3_Export fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { return REFUSE(c, NO_CONFIGURATION); }
FMI3_Export fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { return REFUSE(c, NO_CONFIGURATION); }

#define NO_CLOCKS "the FMU has no clocks"
FMI3_Export fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                              fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    (void)vr, (void)nvr, (void)intervals, (void)qualifiers;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                               fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                               fmi3IntervalQualifier qualifiers[])
{
    (void)vr, (void)nvr, (void)counters, (void)resolutions, (void)qualifiers;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                           fmi3Float64 shifts[])
{
    (void)vr, (void)nvr, (void)shifts;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                            fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                              const fmi3Float64 intervals[])
{
    (void)vr, (void)nvr, (void)intervals;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                               const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                           const fmi3Float64 shifts[])
{
    (void)vr, (void)nvr, (void)shifts;
    return REFUSE(c, NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    return REFUSE(c, NO_CLOCKS);
}

/* Model exchange and scheduled execution: exported (importers load every function), refused for a
   co-simulation instance, the only kind there is. */
#define NOT_ME "this is a co-simulation instance (the FMU provides no model exchange)"
FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { return REFUSE(c, NOT_ME); }

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    return REFUSE(c, NOT_ME);
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time)
{
    (void)time;
    return REFUSE(c, NOT_ME);
}

#define ME_ARRAY(name, qualifier)                                                                        \
    FMI3_Export fmi3Status name(fmi3Instance c, qualifier fmi3Float64 values[], size_t n)                \
    {                                                                                                    \
        (void)values, (void)n;                                                                           \
        return REFUSE(c, NOT_ME);                                                                        \
    }
ME_ARRAY(fmi3SetContinuousStates, const)
ME_ARRAY(fmi3GetContinuousStateDerivatives, )
ME_ARRAY(fmi3GetEventIndicators, )
ME_ARRAY(fmi3GetContinuousStates, )
ME_ARRAY(fmi3GetNominalsOfContinuousStates, )

FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n)
{
    (void)n;
    return REFUSE(c, NOT_ME);
}

FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n)
{
    (void)n;
    return REFUSE(c, NOT_ME);
}

FMI3_Export fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clockReference,
                                                  fmi3Float64 activationTime)
{
    (void)clockReference, (void)activationTime;
    return REFUSE(c, "this is a co-simulation instance (the FMU provides no scheduled execution)");
}
