/*
 * fmi2_api.c - the FMI 2.0 API (co-simulation and Model Exchange) over the
 * shared runtime.
 *
 * Only translation lives here: argument adaptation, status mapping, and the
 * FMI 2.0 logger signature. Real, Integer and Boolean variables map to the
 * runtime's typed access (FMI2 Real = Float64/Float32, Integer = Int8..Int32,
 * UInt8, UInt16); String is rejected with a logged error. The Model Exchange
 * functions are always exported; they fail cleanly on a co-simulation-only model.
 */
#include <stdlib.h>

#include "fmi2Functions.h"
#include "runtime.h"

#define INST ((Instance *)c)
#define CHECK_INST() do { if (!c) return fmi2Error; } while (0)

static fmi2Status to_fmi2(RtStatus s)
{
    switch (s) {
    case RT_OK: return fmi2OK;
    case RT_WARNING: return fmi2Warning;
    case RT_DISCARD: return fmi2Discard;
    case RT_FATAL: return fmi2Fatal;
    default: return fmi2Error;
    }
}

typedef struct {
    fmi2CallbackFunctions callbacks;
} Fmi2Env;

static void fmi2_log(void *env, const char *name, LogLevel level, const char *category,
                     const char *message)
{
    const fmi2CallbackFunctions *cb = env;
    fmi2Status st = level == LOG_ERROR ? fmi2Error : (level == LOG_WARNING ? fmi2Warning : fmi2OK);
    if (cb && cb->logger) cb->logger(cb->componentEnvironment, name, st, category, message);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories; (void)categories;
    CHECK_INST();
    return to_fmi2(rt_set_logging(INST, loggingOn));
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation; (void)visible;
    /* The callbacks struct may not outlive this call: keep our own copy. */
    Fmi2Env *env = calloc(1, sizeof *env);
    if (!env) return NULL;
    if (functions) env->callbacks = *functions;
    if (fmuType != fmi2CoSimulation && fmuType != fmi2ModelExchange) {
        fmi2_log(&env->callbacks, instanceName, LOG_ERROR, "logStatusError",
                 "fmi2Instantiate: fmuType is neither fmi2ModelExchange nor fmi2CoSimulation");
        free(env);
        return NULL;
    }
    Instance *inst = rt_instantiate(instanceName, fmuGUID,
                                    fmuType == fmi2ModelExchange ? RT_MODEL_EXCHANGE : RT_COSIMULATION,
                                    fmi2_log, &env->callbacks, loggingOn);
    if (!inst) free(env);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    if (!c) return;
    void *env = INST->log_env;
    rt_free(INST);
    free(env);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    CHECK_INST();
    return to_fmi2(rt_setup_experiment(INST, startTime));
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_enter_initialization(INST));
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_exit_initialization(INST));
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_terminate(INST));
}

fmi2Status fmi2Reset(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_reset(INST));
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    CHECK_INST();
    return to_fmi2(rt_get(INST, "getFloat64/getReal", RT_FMI2_REAL, vr, nvr, value));
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    CHECK_INST();
    return to_fmi2(rt_set(INST, "setFloat64/setReal", RT_FMI2_REAL, vr, nvr, value));
}

/* Integer and Boolean values travel through the runtime as doubles, in chunks. */
#define CHUNK 64

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    double buf[CHUNK];
    CHECK_INST();
    for (size_t i = 0; i < nvr; i += CHUNK) {
        size_t k = nvr - i < CHUNK ? nvr - i : CHUNK;
        RtStatus st = rt_get(INST, "fmi2GetInteger", RT_FMI2_INTEGER, vr + i, k, buf);
        if (st != RT_OK) return to_fmi2(st);
        for (size_t j = 0; j < k; ++j) value[i + j] = (fmi2Integer)buf[j];
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    double buf[CHUNK];
    CHECK_INST();
    for (size_t i = 0; i < nvr; i += CHUNK) {
        size_t k = nvr - i < CHUNK ? nvr - i : CHUNK;
        RtStatus st = rt_get(INST, "fmi2GetBoolean", RT_TYPE(TYPE_BOOLEAN), vr + i, k, buf);
        if (st != RT_OK) return to_fmi2(st);
        for (size_t j = 0; j < k; ++j) value[i + j] = buf[j] != 0.0 ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    double buf[CHUNK];
    CHECK_INST();
    for (size_t i = 0; i < nvr; i += CHUNK) {
        size_t k = nvr - i < CHUNK ? nvr - i : CHUNK;
        for (size_t j = 0; j < k; ++j) buf[j] = (double)value[i + j];
        RtStatus st = rt_set(INST, "fmi2SetInteger", RT_FMI2_INTEGER, vr + i, k, buf);
        if (st != RT_OK) return to_fmi2(st);
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    double buf[CHUNK];
    CHECK_INST();
    for (size_t i = 0; i < nvr; i += CHUNK) {
        size_t k = nvr - i < CHUNK ? nvr - i : CHUNK;
        for (size_t j = 0; j < k; ++j) buf[j] = value[i + j] ? 1.0 : 0.0;
        RtStatus st = rt_set(INST, "fmi2SetBoolean", RT_TYPE(TYPE_BOOLEAN), vr + i, k, buf);
        if (st != RT_OK) return to_fmi2(st);
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    (void)vr; (void)value;
    CHECK_INST();
    return to_fmi2(rt_no_such_type(INST, "fmi2GetString", nvr));
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    (void)vr; (void)value;
    CHECK_INST();
    return to_fmi2(rt_no_such_type(INST, "fmi2SetString", nvr));
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    CHECK_INST();
    return to_fmi2(rt_get_state(INST, (RtState **)FMUstate));
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    CHECK_INST();
    return to_fmi2(rt_set_state(INST, (const RtState *)FMUstate));
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    CHECK_INST();
    return to_fmi2(rt_free_state(INST, (RtState **)FMUstate));
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)FMUstate;
    CHECK_INST();
    *size = rt_serialized_size(INST);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    CHECK_INST();
    return to_fmi2(rt_serialize(INST, (const RtState *)FMUstate,
                                (unsigned char *)serializedState, size));
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    CHECK_INST();
    return to_fmi2(rt_deserialize(INST, (const unsigned char *)serializedState, size,
                                  (RtState **)FMUstate));
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown;
    (void)dvUnknown;
    CHECK_INST();
    return to_fmi2(rt_unsupported(INST, "fmi2GetDirectionalDerivative"));
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK_INST();
    return to_fmi2(rt_unsupported(INST, "fmi2SetRealInputDerivatives"));
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK_INST();
    return to_fmi2(rt_unsupported(INST, "fmi2GetRealOutputDerivatives"));
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_INST();
    RtStatus st = rt_do_step(INST, currentCommunicationPoint, communicationStepSize);
    /* The model asked to end the simulation: Discard, fmi2Terminated reports why. */
    if ((st == RT_OK || st == RT_WARNING) && INST->terminate_requested) return fmi2Discard;
    return to_fmi2(st);
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_unsupported(INST, "fmi2CancelStep (steps are synchronous)"));
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    CHECK_INST();
    *value = INST->phase == PHASE_ERROR ? fmi2Error : fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    CHECK_INST();
    if (s == fmi2LastSuccessfulTime) {
        *value = INST->time;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s; (void)value;
    CHECK_INST();
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    CHECK_INST();
    if (s == fmi2Terminated) {
        *value = INST->terminate_requested ? fmi2True : fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s; (void)value;
    CHECK_INST();
    return fmi2Discard;
}

/* ---- Model Exchange ------------------------------------------------------ */

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_enter_event_mode(INST));
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo)
{
    RtEventInfo info;
    CHECK_INST();
    RtStatus st = rt_update_discrete_states(INST, &info);
    if ((st == RT_OK || st == RT_WARNING) && eventInfo) {
        eventInfo->newDiscreteStatesNeeded = info.needs_update ? fmi2True : fmi2False;
        eventInfo->terminateSimulation = info.terminate ? fmi2True : fmi2False;
        eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
        eventInfo->valuesOfContinuousStatesChanged = info.states_changed ? fmi2True : fmi2False;
        eventInfo->nextEventTimeDefined = info.next_time_defined ? fmi2True : fmi2False;
        eventInfo->nextEventTime = info.next_time;
    }
    return to_fmi2(st);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    CHECK_INST();
    return to_fmi2(rt_enter_continuous_time_mode(INST));
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    int enter = 0, terminate = 0;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_INST();
    RtStatus st = rt_completed_integrator_step(INST, &enter, &terminate);
    if (enterEventMode) *enterEventMode = enter ? fmi2True : fmi2False;
    if (terminateSimulation) *terminateSimulation = terminate ? fmi2True : fmi2False;
    return to_fmi2(st);
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    CHECK_INST();
    return to_fmi2(rt_set_time(INST, time));
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    CHECK_INST();
    return to_fmi2(rt_set_continuous_states(INST, x, nx));
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    CHECK_INST();
    return to_fmi2(rt_get_derivatives(INST, derivatives, nx));
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    CHECK_INST();
    return to_fmi2(rt_get_event_indicators(INST, eventIndicators, ni));
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    CHECK_INST();
    return to_fmi2(rt_get_continuous_states(INST, x, nx));
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    CHECK_INST();
    return to_fmi2(rt_get_nominals(INST, x_nominal, nx));
}
