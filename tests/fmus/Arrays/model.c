/*
 * Arrays: an FMI 3.0 co-simulation test FMU with array variables and every
 * numeric output type the project's framework (fmus/framework) does not have:
 * Float64 and Float32 and Int32 arrays, Int64, UInt64, Int8, UInt16, UInt32,
 * an Enumeration and a String. Written directly against the FMI 3 headers
 * (the framework has no arrays, enumerations or strings); modelDescription.xml
 * beside this file declares the variables (value references as below), and
 * stubs.c exports the FMI functions this model does not implement.
 *
 * After n completed steps at time t (h the last step size):
 *   x[i]   (Float64[2]) lag toward the input u[i] with time constant tau[i] = i + 1:
 *          x[i] := u[i] + (x[i] - u[i]) exp(-h / tau[i])
 *   y32[i] (Float32[3]) (float)(t * (i + 1) / 3)
 *   k[i]   (Int32[2][2], row-major) n * (i + 1)
 *   count  (Int64)  (int64)big_start + n      steps (UInt64) n
 *   i8     (Int8)   -(n mod 100)              u16 (UInt16) (1000 n) mod 65536
 *   u32    (UInt32) 100000 n                  mode (Enumeration Mode) 1 + n mod 3
 *   odd    (Boolean) n odd                    k_out (Int32) 3 k_in
 *   label  (String) "step"
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

enum { VR_TIME, VR_U, VR_X, VR_COUNT, VR_STEPS, VR_I8, VR_U16, VR_U32, VR_MODE, VR_LABEL,
       VR_Y32, VR_K, VR_ODD, VR_K_IN, VR_K_OUT, VR_BIG_START };

typedef struct {
    double time, u[2], x[2], big_start;
    int64_t n;
    int32_t k_in;
} Instance;

#define INST ((Instance *)instance)

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)eventModeUsed; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)instanceEnvironment; (void)logMessage;
    (void)intermediateUpdate;
    if (strcmp(instantiationToken, "{a7e2c1d0-3b4f-4e5a-9c6d-7e8f90a1b2c3}") != 0) return NULL;
    Instance *inst = calloc(1, sizeof(Instance));
    if (inst != NULL) inst->u[0] = inst->u[1] = 1.0; /* the start values of u */
    return inst;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi3OK;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    INST->time = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    for (int i = 0; i < 2; ++i)
        INST->x[i] = INST->u[i] + (INST->x[i] - INST->u[i]) * exp(-communicationStepSize / (i + 1));
    INST->time = currentCommunicationPoint + communicationStepSize;
    INST->n += 1;
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = fmi3False;
    *lastSuccessfulTime = INST->time;
    return fmi3OK;
}

/* Copies the values of scalar (size 1) or array variables in value-reference order. */
#define GETTER(fn, T, body)                                                                 \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,        \
                  T values[], size_t nValues)                                              \
    {                                                                                      \
        size_t at = 0;                                                                     \
        for (size_t r = 0; r < nvr; ++r) {                                                 \
            switch (vr[r]) {                                                               \
            body                                                                           \
            default: return fmi3Error;                                                     \
            }                                                                              \
        }                                                                                  \
        return at == nValues ? fmi3OK : fmi3Error;                                         \
    }
#define ONE(ref, expr) case ref: values[at++] = (expr); break;
#define MANY(ref, count, expr) \
    case ref: for (int i = 0; i < (count); ++i) values[at++] = (expr); break;

GETTER(fmi3GetFloat64, fmi3Float64,
       ONE(VR_TIME, INST->time) MANY(VR_U, 2, INST->u[i]) MANY(VR_X, 2, INST->x[i])
       ONE(VR_BIG_START, INST->big_start))
GETTER(fmi3GetFloat32, fmi3Float32, MANY(VR_Y32, 3, (float)(INST->time * (i + 1) / 3)))
GETTER(fmi3GetInt8, fmi3Int8, ONE(VR_I8, (int8_t)-(INST->n % 100)))
GETTER(fmi3GetUInt16, fmi3UInt16, ONE(VR_U16, (uint16_t)((1000 * INST->n) % 65536)))
GETTER(fmi3GetUInt32, fmi3UInt32, ONE(VR_U32, (uint32_t)(100000 * INST->n)))
GETTER(fmi3GetInt32, fmi3Int32,
       MANY(VR_K, 4, (int32_t)(INST->n * (i + 1))) ONE(VR_K_IN, INST->k_in)
       ONE(VR_K_OUT, 3 * INST->k_in))
GETTER(fmi3GetInt64, fmi3Int64,
       ONE(VR_COUNT, (int64_t)INST->big_start + INST->n) ONE(VR_MODE, 1 + INST->n % 3))
GETTER(fmi3GetUInt64, fmi3UInt64, ONE(VR_STEPS, (uint64_t)INST->n))
GETTER(fmi3GetBoolean, fmi3Boolean, ONE(VR_ODD, INST->n % 2 == 1))
GETTER(fmi3GetString, fmi3String, ONE(VR_LABEL, "step"))

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues)
{
    size_t at = 0;
    for (size_t r = 0; r < nvr; ++r) {
        if (vr[r] == VR_U) {
            INST->u[0] = values[at++];
            INST->u[1] = values[at++];
        } else if (vr[r] == VR_BIG_START) {
            INST->big_start = values[at++];
        } else {
            return fmi3Error;
        }
    }
    return at == nValues ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Int32 values[], size_t nValues)
{
    if (nvr != 1 || nValues != 1 || vr[0] != VR_K_IN) return fmi3Error;
    INST->k_in = values[0];
    return fmi3OK;
}
