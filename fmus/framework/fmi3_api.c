/*
 * fmi3_api.c - the FMI 3.0 API (co-simulation and Model Exchange) over the
 * shared runtime.
 *
 * Only translation lives here. Every function of fmi3Functions.h is exported
 * (the standard requires it); those outside co-simulation without event mode,
 * Model Exchange, and the Float*, Int*, UInt* and Boolean types (clocks,
 * String, Binary, scheduled execution, derivatives) log an error and return
 * fmi3Error.
 */
#include <stdlib.h>

#include "fmi3Functions.h"
#include "runtime.h"

#define INST ((Instance *)instance)
#define CHECK_INST() do { if (!instance) return fmi3Error; } while (0)
#define UNSUPPORTED(fn) do { CHECK_INST(); return to_fmi3(rt_unsupported(INST, fn)); } while (0)

static fmi3Status to_fmi3(RtStatus s)
{
    switch (s) {
    case RT_OK: return fmi3OK;
    case RT_WARNING: return fmi3Warning;
    case RT_DISCARD: return fmi3Discard;
    case RT_FATAL: return fmi3Fatal;
    default: return fmi3Error;
    }
}

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Fmi3Env;

static void fmi3_log(void *env, const char *name, LogLevel level, const char *category,
                     const char *message)
{
    const Fmi3Env *e = env;
    fmi3Status st = level == LOG_ERROR ? fmi3Error : (level == LOG_WARNING ? fmi3Warning : fmi3OK);
    (void)name;
    if (e && e->log) e->log(e->env, st, category, message);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)nCategories; (void)categories;
    CHECK_INST();
    return to_fmi3(rt_set_logging(INST, loggingOn));
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)resourcePath; (void)visible;
    Fmi3Env *env = calloc(1, sizeof *env);
    if (!env) return NULL;
    env->env = instanceEnvironment;
    env->log = logMessage;
    Instance *inst = rt_instantiate(instanceName, instantiationToken, RT_MODEL_EXCHANGE,
                                    fmi3_log, env, loggingOn);
    if (!inst) free(env);
    return inst;
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    Fmi3Env *env = calloc(1, sizeof *env);
    if (!env) return NULL;
    env->env = instanceEnvironment;
    env->log = logMessage;
    if (eventModeUsed) {
        fmi3_log(env, instanceName, LOG_ERROR, "logStatusError",
                 "fmi3InstantiateCoSimulation: event mode is not supported (hasEventMode=false)");
        free(env);
        return NULL;
    }
    Instance *inst = rt_instantiate(instanceName, instantiationToken, RT_COSIMULATION,
                                    fmi3_log, env, loggingOn);
    if (!inst) free(env);
    return inst;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: only co-simulation is supported");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    if (!instance) return;
    void *env = INST->log_env;
    rt_free(INST);
    free(env);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    CHECK_INST();
    if (rt_setup_experiment(INST, startTime) != RT_OK) return fmi3Error;
    return to_fmi3(rt_enter_initialization(INST));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    CHECK_INST();
    return to_fmi3(rt_exit_initialization(INST));
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    CHECK_INST();
    return to_fmi3(rt_enter_event_mode(INST));
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    CHECK_INST();
    return to_fmi3(rt_terminate(INST));
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    CHECK_INST();
    return to_fmi3(rt_reset(INST));
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    CHECK_INST();
    if (nValues != nValueReferences)
        return to_fmi3(rt_unsupported(INST, "fmi3GetFloat64 with arrays (nValues != nValueReferences)"));
    return to_fmi3(rt_get(INST, "getFloat64/getReal", RT_TYPE(TYPE_FLOAT64), valueReferences,
                          nValueReferences, values));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    CHECK_INST();
    if (nValues != nValueReferences)
        return to_fmi3(rt_unsupported(INST, "fmi3SetFloat64 with arrays (nValues != nValueReferences)"));
    return to_fmi3(rt_set(INST, "setFloat64/setReal", RT_TYPE(TYPE_FLOAT64), valueReferences,
                          nValueReferences, values));
}

/* The other types travel through the runtime as doubles, in chunks (the
   runtime guarantees that a stored value fits its variable's type). */
#define CHUNK 64

#define TYPED_GET(fn, T, type, convert)                                                 \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],    \
                  size_t nValueReferences, T values[], size_t nValues)                  \
    {                                                                                   \
        double buf[CHUNK];                                                              \
        CHECK_INST();                                                                   \
        if (nValues != nValueReferences)                                                \
            return to_fmi3(rt_unsupported(INST, #fn " with arrays"));                   \
        for (size_t i = 0; i < nValueReferences; i += CHUNK) {                          \
            size_t k = nValueReferences - i < CHUNK ? nValueReferences - i : CHUNK;     \
            RtStatus st = rt_get(INST, #fn, RT_TYPE(type), valueReferences + i, k, buf); \
            if (st != RT_OK) return to_fmi3(st);                                        \
            for (size_t j = 0; j < k; ++j) values[i + j] = convert(T, buf[j]);          \
        }                                                                               \
        return fmi3OK;                                                                  \
    }

#define TYPED_SET(fn, T, type)                                                          \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],    \
                  size_t nValueReferences, const T values[], size_t nValues)            \
    {                                                                                   \
        double buf[CHUNK];                                                              \
        CHECK_INST();                                                                   \
        if (nValues != nValueReferences)                                                \
            return to_fmi3(rt_unsupported(INST, #fn " with arrays"));                   \
        for (size_t i = 0; i < nValueReferences; i += CHUNK) {                          \
            size_t k = nValueReferences - i < CHUNK ? nValueReferences - i : CHUNK;     \
            for (size_t j = 0; j < k; ++j) buf[j] = (double)values[i + j];              \
            RtStatus st = rt_set(INST, #fn, RT_TYPE(type), valueReferences + i, k, buf); \
            if (st != RT_OK) return to_fmi3(st);                                        \
        }                                                                               \
        return fmi3OK;                                                                  \
    }

#define AS_NUMBER(T, x) ((T)(x))
#define AS_BOOLEAN(T, x) ((x) != 0.0 ? fmi3True : fmi3False)

TYPED_GET(fmi3GetFloat32, fmi3Float32, TYPE_FLOAT32, AS_NUMBER)
TYPED_GET(fmi3GetInt8, fmi3Int8, TYPE_INT8, AS_NUMBER)
TYPED_GET(fmi3GetUInt8, fmi3UInt8, TYPE_UINT8, AS_NUMBER)
TYPED_GET(fmi3GetInt16, fmi3Int16, TYPE_INT16, AS_NUMBER)
TYPED_GET(fmi3GetUInt16, fmi3UInt16, TYPE_UINT16, AS_NUMBER)
TYPED_GET(fmi3GetInt32, fmi3Int32, TYPE_INT32, AS_NUMBER)
TYPED_GET(fmi3GetUInt32, fmi3UInt32, TYPE_UINT32, AS_NUMBER)
TYPED_GET(fmi3GetInt64, fmi3Int64, TYPE_INT64, AS_NUMBER)
TYPED_GET(fmi3GetUInt64, fmi3UInt64, TYPE_UINT64, AS_NUMBER)
TYPED_GET(fmi3GetBoolean, fmi3Boolean, TYPE_BOOLEAN, AS_BOOLEAN)
TYPED_SET(fmi3SetFloat32, fmi3Float32, TYPE_FLOAT32)
TYPED_SET(fmi3SetInt8, fmi3Int8, TYPE_INT8)
TYPED_SET(fmi3SetUInt8, fmi3UInt8, TYPE_UINT8)
TYPED_SET(fmi3SetInt16, fmi3Int16, TYPE_INT16)
TYPED_SET(fmi3SetUInt16, fmi3UInt16, TYPE_UINT16)
TYPED_SET(fmi3SetInt32, fmi3Int32, TYPE_INT32)
TYPED_SET(fmi3SetUInt32, fmi3UInt32, TYPE_UINT32)
TYPED_SET(fmi3SetInt64, fmi3Int64, TYPE_INT64)
TYPED_SET(fmi3SetUInt64, fmi3UInt64, TYPE_UINT64)
TYPED_SET(fmi3SetBoolean, fmi3Boolean, TYPE_BOOLEAN)

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3String values[], size_t nValues)
{
    (void)valueReferences; (void)values; (void)nValues;
    CHECK_INST();
    return to_fmi3(rt_no_such_type(INST, "fmi3GetString", nValueReferences));
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3String values[], size_t nValues)
{
    (void)valueReferences; (void)values; (void)nValues;
    CHECK_INST();
    return to_fmi3(rt_no_such_type(INST, "fmi3SetString", nValueReferences));
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues)
{
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    CHECK_INST();
    return to_fmi3(rt_no_such_type(INST, "fmi3GetBinary", nValueReferences));
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues)
{
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    CHECK_INST();
    return to_fmi3(rt_no_such_type(INST, "fmi3SetBinary", nValueReferences));
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[])
{
    (void)valueReferences; (void)values;
    CHECK_INST();
    return to_fmi3(rt_no_such_type(INST, "fmi3GetClock", nValueReferences));
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[])
{
    (void)valueReferences; (void)values;
    CHECK_INST();
    return to_fmi3(rt_no_such_type(INST, "fmi3SetClock", nValueReferences));
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference; (void)nDependencies;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies)
{
    (void)dependent; (void)elementIndicesOfDependent; (void)independents;
    (void)elementIndicesOfIndependents; (void)dependencyKinds; (void)nDependencies;
    UNSUPPORTED("fmi3GetVariableDependencies");
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    CHECK_INST();
    return to_fmi3(rt_get_state(INST, (RtState **)FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    CHECK_INST();
    return to_fmi3(rt_set_state(INST, (const RtState *)FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    CHECK_INST();
    return to_fmi3(rt_free_state(INST, (RtState **)FMUState));
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    (void)FMUState;
    CHECK_INST();
    *size = rt_serialized_size(INST);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size)
{
    CHECK_INST();
    return to_fmi3(rt_serialize(INST, (const RtState *)FMUState, serializedState, size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState)
{
    CHECK_INST();
    return to_fmi3(rt_deserialize(INST, serializedState, size, (RtState **)FMUState));
}

#define NO_DERIVATIVE(fn)                                                               \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference unknowns[],           \
                  size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,  \
                  const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],    \
                  size_t nSensitivity)                                                  \
    {                                                                                   \
        (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed;       \
        (void)nSeed; (void)sensitivity; (void)nSensitivity;                             \
        UNSUPPORTED(#fn);                                                               \
    }
NO_DERIVATIVE(fmi3GetDirectionalDerivative)
NO_DERIVATIVE(fmi3GetAdjointDerivative)

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterConfigurationMode"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { UNSUPPORTED("fmi3ExitConfigurationMode"); }

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences; (void)nValueReferences; (void)intervals; (void)qualifiers;
    UNSUPPORTED("fmi3GetIntervalDecimal");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    (void)qualifiers;
    UNSUPPORTED("fmi3GetIntervalFraction");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    UNSUPPORTED("fmi3GetShiftDecimal");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    UNSUPPORTED("fmi3GetShiftFraction");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    (void)valueReferences; (void)nValueReferences; (void)intervals;
    UNSUPPORTED("fmi3SetIntervalDecimal");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    UNSUPPORTED("fmi3SetIntervalFraction");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    UNSUPPORTED("fmi3SetShiftDecimal");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    UNSUPPORTED("fmi3SetShiftFraction");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { UNSUPPORTED("fmi3EvaluateDiscreteStates"); }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    RtEventInfo info;
    CHECK_INST();
    RtStatus st = rt_update_discrete_states(INST, &info);
    if (st == RT_OK || st == RT_WARNING) {
        if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = info.needs_update ? fmi3True : fmi3False;
        if (terminateSimulation) *terminateSimulation = info.terminate ? fmi3True : fmi3False;
        if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = fmi3False;
        if (valuesOfContinuousStatesChanged)
            *valuesOfContinuousStatesChanged = info.states_changed ? fmi3True : fmi3False;
        if (nextEventTimeDefined) *nextEventTimeDefined = info.next_time_defined ? fmi3True : fmi3False;
        if (nextEventTime) *nextEventTime = info.next_time;
    }
    return to_fmi3(st);
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    CHECK_INST();
    return to_fmi3(rt_enter_continuous_time_mode(INST));
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    int enter = 0, terminate = 0;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_INST();
    RtStatus st = rt_completed_integrator_step(INST, &enter, &terminate);
    if (enterEventMode) *enterEventMode = enter ? fmi3True : fmi3False;
    if (terminateSimulation) *terminateSimulation = terminate ? fmi3True : fmi3False;
    return to_fmi3(st);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    CHECK_INST();
    return to_fmi3(rt_set_time(INST, time));
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    CHECK_INST();
    return to_fmi3(rt_set_continuous_states(INST, continuousStates, nContinuousStates));
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
{
    CHECK_INST();
    return to_fmi3(rt_get_derivatives(INST, derivatives, nContinuousStates));
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators)
{
    CHECK_INST();
    return to_fmi3(rt_get_event_indicators(INST, eventIndicators, nEventIndicators));
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    CHECK_INST();
    return to_fmi3(rt_get_continuous_states(INST, continuousStates, nContinuousStates));
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates)
{
    CHECK_INST();
    return to_fmi3(rt_get_nominals(INST, nominals, nContinuousStates));
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    CHECK_INST();
    if (nEventIndicators) *nEventIndicators = rt_n_event_indicators();
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    CHECK_INST();
    if (nContinuousStates) *nContinuousStates = rt_n_states();
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterStepMode (no event mode)"); }

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues)
{
    (void)valueReferences; (void)nValueReferences; (void)orders; (void)values; (void)nValues;
    UNSUPPORTED("fmi3GetOutputDerivatives");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_INST();
    fmi3Status st = to_fmi3(rt_do_step(INST, currentCommunicationPoint, communicationStepSize));
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    /* A model's request to end the simulation: status OK (or Warning), the step is done. */
    if (terminateSimulation) *terminateSimulation = INST->terminate_requested ? fmi3True : fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = INST->time;
    return st;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference; (void)activationTime;
    UNSUPPORTED("fmi3ActivateModelPartition");
}
