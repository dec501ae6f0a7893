/*
 * runtime.h - the shared FMI runtime: instance life cycle, call-sequence state
 * machine, range checks from the variable table, logging through the importer's
 * logger, reset, and FMU state save/restore/serialization.
 *
 * It is independent of the FMI version: fmi2_api.c and fmi3_api.c translate
 * their calls into these functions and map RtStatus to fmi2Status/fmi3Status.
 * No model code lives here; the model is reached only through `MODEL`.
 */
#ifndef COSIM_RUNTIME_H
#define COSIM_RUNTIME_H

#include <stddef.h>
#include "model.h"

/* Value reference of the FMI 3.0 independent variable `time` (not in the table). */
#define RT_VR_TIME 1000000u

typedef enum { RT_OK, RT_WARNING, RT_ERROR } RtStatus;

typedef enum {
    PHASE_INSTANTIATED,   /* after instantiate or reset: set parameters and inputs */
    PHASE_INIT,           /* initialization mode */
    PHASE_STEP,           /* step mode (FMI2 stepComplete) */
    PHASE_TERMINATED,
    PHASE_ERROR           /* after an error: only get, reset, free allowed */
} Phase;

/* Logger of the importer, already adapted by the API layer to one signature. */
typedef void (*RtLogFn)(void *env, const char *instance_name, LogLevel level,
                        const char *category, const char *message);

typedef struct Instance {
    char *name;
    RtLogFn log_fn;
    void *log_env;
    int logging_on;          /* debug (LOG_OK) messages only when on */
    ModelLogger model_logger;
    Phase phase;
    double start_time;
    double time;
    double *values;          /* indexed by value reference */
    void *state;             /* model's private POD state, MODEL.state_size bytes */
} Instance;

/* Instantiate: token must equal MODEL.guid. Returns NULL (after logging) on failure. */
Instance *rt_instantiate(const char *name, const char *token,
                         RtLogFn log_fn, void *log_env, int logging_on);
void rt_free(Instance *inst);
void rt_log(const Instance *inst, LogLevel level, const char *fmt, ...);
RtStatus rt_set_logging(Instance *inst, int on);

RtStatus rt_setup_experiment(Instance *inst, double start_time);
RtStatus rt_enter_initialization(Instance *inst);
RtStatus rt_exit_initialization(Instance *inst);
RtStatus rt_do_step(Instance *inst, double t, double h);
RtStatus rt_terminate(Instance *inst);
RtStatus rt_reset(Instance *inst);

RtStatus rt_get_float64(Instance *inst, const unsigned int vr[], size_t n, double out[]);
RtStatus rt_set_float64(Instance *inst, const unsigned int vr[], size_t n, const double in[]);
/* Get/set of a type the models do not have: ok for n == 0, else error. */
RtStatus rt_no_such_type(Instance *inst, const char *function, size_t n);
/* A function of the API that this framework does not support. */
RtStatus rt_unsupported(Instance *inst, const char *function);

/* FMU state: an opaque copy of phase, time, values[] and the model state. */
typedef struct RtState RtState;
RtStatus rt_get_state(Instance *inst, RtState **state);
RtStatus rt_set_state(Instance *inst, const RtState *state);
RtStatus rt_free_state(Instance *inst, RtState **state);
size_t rt_serialized_size(const Instance *inst);
RtStatus rt_serialize(Instance *inst, const RtState *state, unsigned char *buf, size_t size);
RtStatus rt_deserialize(Instance *inst, const unsigned char *buf, size_t size, RtState **state);

#endif
