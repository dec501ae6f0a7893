/* cosim_stepper.h: one FMU co-simulation step (set inputs, doStep, get outputs) in one call. */
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include "cosim_stepper.h"

#define EXPORT __attribute__((visibility("default")))

/* Discard, Error, Fatal (and Pending, FMI 2's fmi2Pending = 5) stop the step, as in the importer. */
static int failed(int status)
{
    return status > 1;
}

static int step_fmi2(CosimStepper *s, double t, double h)
{
    if (s->n_in > 0) {
        s->status[COSIM_CALL_SET] = (int)s->fmi2_set_real(s->instance, s->in_vr, s->n_in, s->in_values);
        if (failed(s->status[COSIM_CALL_SET]))
            return COSIM_STEP_SET;
    }
    s->status[COSIM_CALL_DO_STEP] = (int)s->fmi2_do_step(s->instance, t, h, fmi2True);
    if (failed(s->status[COSIM_CALL_DO_STEP]))
        return COSIM_STEP_DO_STEP;
    if (s->n_out > 0) {
        s->status[COSIM_CALL_GET] = (int)s->fmi2_get_real(s->instance, s->out_vr, s->n_out, s->out_values);
        if (failed(s->status[COSIM_CALL_GET]))
            return COSIM_STEP_GET;
    }
    return COSIM_STEP_DONE;
}

static int step_fmi3(CosimStepper *s, double t, double h)
{
    fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
    fmi3Float64 last = t;
    int status;

    if (s->n_in > 0) {
        s->status[COSIM_CALL_SET] = (int)s->fmi3_set_float64(s->instance, s->in_vr, s->n_in,
                                                               s->in_values, s->n_in);
        if (failed(s->status[COSIM_CALL_SET]))
            return COSIM_STEP_SET;
    }
    status = (int)s->fmi3_do_step(s->instance, t, h, fmi3True, &event, &terminate, &early, &last);
    s->status[COSIM_CALL_DO_STEP] = status;
    s->event_handling_needed = event ? 1 : 0;
    s->terminate_simulation = terminate ? 1 : 0;
    s->early_return = early ? 1 : 0;
    s->last_successful_time = last;
    if (failed(status))
        return COSIM_STEP_DO_STEP;
    if (terminate)
        return COSIM_STEP_TERMINATE;
    if (s->n_out > 0) {
        s->status[COSIM_CALL_GET] = (int)s->fmi3_get_float64(s->instance, s->out_vr, s->n_out,
                                                               s->out_values, s->n_out);
        if (failed(s->status[COSIM_CALL_GET]))
            return COSIM_STEP_GET;
    }
    return COSIM_STEP_DONE;
}

EXPORT int cosim_stepper_step(CosimStepper *stepper, double t, double h)
{
    stepper->status[COSIM_CALL_SET] = -1;
    stepper->status[COSIM_CALL_DO_STEP] = -1;
    stepper->status[COSIM_CALL_GET] = -1;
    stepper->stopped_by = stepper->fmi_version == 3 ? step_fmi3(stepper, t, h) : step_fmi2(stepper, t, h);
    return stepper->stopped_by;
}

EXPORT int cosim_stepper_step_at(CosimStepper *stepper)
{
    return cosim_stepper_step(stepper, stepper->t, stepper->h);
}

EXPORT void cosim_stepper_fmi2_logger(fmi2ComponentEnvironment environment, fmi2String instance_name,
                                      fmi2Status status, fmi2String category, fmi2String message, ...)
{
    const CosimFmi2Log *log = (const CosimFmi2Log *)environment;
    char buffer[COSIM_LOG_MAX];
    va_list args;

    (void)instance_name;
    if (log == NULL || log->sink == NULL)
        return;
    va_start(args, message);
    vsnprintf(buffer, sizeof buffer, message != NULL ? message : "", args);
    va_end(args);
    log->sink(log->context, (int)status, category, buffer);
}

EXPORT int cosim_stepper_abi(void)
{
    return COSIM_STEPPER_ABI;
}

EXPORT size_t cosim_stepper_size(void)
{
    return sizeof(CosimStepper);
}

EXPORT size_t cosim_stepper_time_offset(void)
{
    return offsetof(CosimStepper, t);
}
