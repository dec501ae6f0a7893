/*
 * fmi2_api.c - the FMI 2.0 co-simulation API over the shared runtime.
 *
 * Only translation lives here: argument adaptation, status mapping, and the
 * FMI 2.0 logger signature. Model Exchange and non-Real types are rejected
 * with a logged error.
 */
#include <stdlib.h>

#include "fmi2Functions.h"
#include "runtime.h"

#define INST ((Instance *)c)
#define CHECK_INST() do { if (!c) return fmi2Error; } while (0)

static fmi2Status to_fmi2(RtStatus s)
{
    return s == RT_OK ? fmi2OK : (s == RT_WARNING ? fmi2Warning : fmi2Error);
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
    if (fmuType != fmi2CoSimulation) {
        fmi2_log(&env->callbacks, instanceName, LOG_ERROR, "logStatusError",
                 "fmi2Instantiate: only co-simulation is supported (fmuType != fmi2CoSimulation)");
        free(env);
        return NULL;
    }
    Instance *inst = rt_instantiate(instanceName, fmuGUID, fmi2_log, &env->callbacks, loggingOn);
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
    return to_fmi2(rt_get_float64(INST, vr, nvr, value));
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    CHECK_INST();
    return to_fmi2(rt_set_float64(INST, vr, nvr, value));
}

#define NO_TYPE(fn, ptype, qual)                                                        \
    fmi2Status fn(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,           \
                  qual ptype value[])                                                   \
    {                                                                                   \
        (void)vr; (void)value;                                                          \
        CHECK_INST();                                                                   \
        return to_fmi2(rt_no_such_type(INST, #fn, nvr));                                \
    }
NO_TYPE(fmi2GetInteger, fmi2Integer, )
NO_TYPE(fmi2GetBoolean, fmi2Boolean, )
NO_TYPE(fmi2GetString, fmi2String, )
NO_TYPE(fmi2SetInteger, fmi2Integer, const)
NO_TYPE(fmi2SetBoolean, fmi2Boolean, const)
NO_TYPE(fmi2SetString, fmi2String, const)

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
    return to_fmi2(rt_do_step(INST, currentCommunicationPoint, communicationStepSize));
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
        *value = fmi2False;
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
