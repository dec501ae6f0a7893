/* One co-simulation step of an FMU in one call: set inputs, doStep, get outputs.
 *
 * Not a model: a helper library for an importer (the platform's FMU host)
 * that drives an FMU already loaded and instantiated by someone else (fmpy).
 * The importer fills a CosimStepper once with the FMU's own FMI function
 * pointers, the instance and the value-reference and value arrays, then
 * calls cosim_stepper_step once per tick (or writes t and h into the struct
 * and calls cosim_stepper_step_at: no double arguments, which a foreign
 * function interface such as ctypes converts at a cost). The calls and their order are
 * exactly those an importer makes one by one:
 *
 *     FMI 2: fmi2SetReal(in), fmi2DoStep(t, h, fmi2True), fmi2GetReal(out)
 *     FMI 3: fmi3SetFloat64(in), fmi3DoStep(t, h, true, ...), fmi3GetFloat64(out)
 *
 * and each call's status is kept, so the importer reports a failure as it
 * would after its own call. Set or get is skipped when it has no variables.
 */
#ifndef COSIM_STEPPER_H
#define COSIM_STEPPER_H

#include <stddef.h>
#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

#define COSIM_STEPPER_ABI 3

/* What stopped a step (cosim_stepper_step's return value and CosimStepper.stopped_by). */
enum {
    COSIM_STEP_DONE = 0,       /* every call returned OK or Warning */
    COSIM_STEP_SET = 1,        /* the set call returned Discard or worse; nothing else was called */
    COSIM_STEP_DO_STEP = 2,    /* doStep returned Discard or worse; get was not called */
    COSIM_STEP_GET = 3,        /* the get call returned Discard or worse */
    COSIM_STEP_TERMINATE = 4   /* FMI 3: doStep OK but terminateSimulation set; get was not called */
};

/* Index of each call in CosimStepper.status. */
enum { COSIM_CALL_SET = 0, COSIM_CALL_DO_STEP = 1, COSIM_CALL_GET = 2 };

typedef struct CosimStepper {
    /* filled once by the importer */
    int fmi_version;                        /* 2 or 3 */
    void *instance;                         /* fmi2Component / fmi3Instance */
    fmi2SetRealTYPE *fmi2_set_real;         /* FMI 2 functions (NULL for FMI 3) */
    fmi2DoStepTYPE *fmi2_do_step;
    fmi2GetRealTYPE *fmi2_get_real;
    fmi3SetFloat64TYPE *fmi3_set_float64;   /* FMI 3 functions (NULL for FMI 2) */
    fmi3DoStepTYPE *fmi3_do_step;
    fmi3GetFloat64TYPE *fmi3_get_float64;
    size_t n_in;                            /* inputs: value references and values */
    const unsigned int *in_vr;
    const double *in_values;
    size_t n_out;                           /* outputs: value references and where they go */
    const unsigned int *out_vr;
    double *out_values;
    /* written by the importer before each cosim_stepper_step_at */
    double t;                               /* communication point */
    double h;                               /* communication step size */
    /* written by every cosim_stepper_step */
    int status[3];                          /* set, doStep, get: FMI status, -1 when not called */
    int stopped_by;                         /* COSIM_STEP_* */
    int event_handling_needed;              /* FMI 3 doStep outputs (0 / 1), 0 for FMI 2 */
    int terminate_simulation;
    int early_return;
    double last_successful_time;
} CosimStepper;

/* One step from communication point t over h; returns stopped_by (COSIM_STEP_DONE when all went well). */
int cosim_stepper_step(CosimStepper *stepper, double t, double h);

/* cosim_stepper_step(stepper, stepper->t, stepper->h). */
int cosim_stepper_step_at(CosimStepper *stepper);

/* FMI 2 logger that routes each instance's messages to its own sink.
 *
 * fmi2CallbackLogger is variadic, so an importer in Python needs a C function to
 * format the message (fmpy's addLoggerProxy keeps one static callback for the
 * whole process: every FMI 2 instance's messages go to the last one set up).
 * Give cosim_stepper_fmi2_logger as callbacks.logger and a CosimFmi2Log of the
 * instance's own as callbacks.componentEnvironment: the message is formatted
 * (at most COSIM_LOG_MAX - 1 bytes) and handed to log->sink(log->context, ...). */
#define COSIM_LOG_MAX 2048

typedef void CosimLogSink(void *context, int status, const char *category, const char *message);

typedef struct CosimFmi2Log {
    CosimLogSink *sink;
    void *context;
} CosimFmi2Log;

void cosim_stepper_fmi2_logger(fmi2ComponentEnvironment environment, fmi2String instance_name,
                               fmi2Status status, fmi2String category, fmi2String message, ...);

/* COSIM_STEPPER_ABI, sizeof(CosimStepper) and the offset of t: the binding checks its mirror of the struct. */
int cosim_stepper_abi(void);
size_t cosim_stepper_size(void);
size_t cosim_stepper_time_offset(void);

#endif
