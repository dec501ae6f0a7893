/*
 * runtime.h - the shared FMI runtime: instance life cycle, call-sequence state
 * machine, range checks from the variable table, typed get/set, logging through
 * the importer's logger, reset, FMU state save/restore/serialization, and Model
 * Exchange (event and continuous-time modes) for models with MODEL_EXTENSION.
 *
 * It is independent of the FMI version: fmi2_api.c and fmi3_api.c translate
 * their calls into these functions and map RtStatus to fmi2Status/fmi3Status.
 * No model code lives here; the model is reached only through `MODEL` and the
 * optional `MODEL_EXTENSION`.
 */
#ifndef COSIM_RUNTIME_H
#define COSIM_RUNTIME_H

#include <stddef.h>
#include "model.h"

/* Value reference of the FMI 3.0 independent variable `time` (not in the table). */
#define RT_VR_TIME 1000000u

typedef enum { RT_OK, RT_WARNING, RT_ERROR, RT_DISCARD, RT_FATAL } RtStatus;

typedef enum { RT_COSIMULATION, RT_MODEL_EXCHANGE } RtInterface;

typedef enum {
    PHASE_INSTANTIATED,   /* after instantiate or reset: set parameters and inputs */
    PHASE_INIT,           /* initialization mode */
    PHASE_STEP,           /* co-simulation step mode (FMI2 stepComplete) */
    PHASE_TERMINATED,
    PHASE_ERROR,          /* after an error: only get, reset, free allowed */
    PHASE_EVENT,          /* Model Exchange event mode */
    PHASE_CONTINUOUS,     /* Model Exchange continuous-time mode */
    PHASE_COUNT
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
    RtInterface interface;
    Phase phase;
    double start_time;
    double time;
    double *values;          /* indexed by value reference */
    void *state;             /* model's private POD state, MODEL.state_size bytes */
    int terminate_requested; /* the model asked to end the simulation */
    int dirty;               /* Model Exchange: evaluate() needed before reading */
    double next_event_time;  /* Model Exchange / integrated CS: INFINITY if none */
    double *work;            /* scratch of the co-simulation integrator */
} Instance;

/* Name of a type ("Int32") and whether x is a value of it (integral and in
   range for integers, 0/1 for Booleans, finite for floats). */
const char *rt_type_name(VarType type);
int rt_value_fits(VarType type, double x);

/* Which model-side interfaces the FMU has (from MODEL_EXTENSION). */
int rt_has_model_exchange(void);
int rt_has_cosimulation(void);

/* Instantiate: token must equal MODEL.guid. Returns NULL (after logging) on failure. */
Instance *rt_instantiate(const char *name, const char *token, RtInterface interface,
                         RtLogFn log_fn, void *log_env, int logging_on);
void rt_free(Instance *inst);
void rt_log(const Instance *inst, LogLevel level, const char *fmt, ...);
RtStatus rt_set_logging(Instance *inst, int on);

RtStatus rt_setup_experiment(Instance *inst, double start_time);
RtStatus rt_enter_initialization(Instance *inst);
RtStatus rt_exit_initialization(Instance *inst);
/* Co-simulation step. RT_OK with inst->terminate_requested set: the step is
   done and the model asks to end the simulation. */
RtStatus rt_do_step(Instance *inst, double t, double h);
RtStatus rt_terminate(Instance *inst);
RtStatus rt_reset(Instance *inst);

/* Typed access. `types` is a mask of RT_TYPE(TYPE_...) bits the calling API
   function accepts (FMI3: one type; FMI2: a class); values travel as doubles. */
#define RT_TYPE(t) (1u << (t))
#define RT_FMI2_REAL (RT_TYPE(TYPE_FLOAT64) | RT_TYPE(TYPE_FLOAT32))
#define RT_FMI2_INTEGER (RT_TYPE(TYPE_INT8) | RT_TYPE(TYPE_UINT8) | RT_TYPE(TYPE_INT16) \
                         | RT_TYPE(TYPE_UINT16) | RT_TYPE(TYPE_INT32))
RtStatus rt_get(Instance *inst, const char *function, unsigned types,
                const unsigned int vr[], size_t n, double out[]);
RtStatus rt_set(Instance *inst, const char *function, unsigned types,
                const unsigned int vr[], size_t n, const double in[]);
/* Get/set of a type no variable can have (String, Binary, Clock): ok for n == 0. */
RtStatus rt_no_such_type(Instance *inst, const char *function, size_t n);
/* A function of the API that this framework does not support. */
RtStatus rt_unsupported(Instance *inst, const char *function);

/* Model Exchange. */
typedef struct {
    int needs_update, terminate, states_changed, next_time_defined;
    double next_time;
} RtEventInfo;
RtStatus rt_enter_event_mode(Instance *inst);
RtStatus rt_update_discrete_states(Instance *inst, RtEventInfo *info);
RtStatus rt_enter_continuous_time_mode(Instance *inst);
RtStatus rt_completed_integrator_step(Instance *inst, int *enter_event_mode, int *terminate);
RtStatus rt_set_time(Instance *inst, double t);
RtStatus rt_set_continuous_states(Instance *inst, const double x[], size_t n);
RtStatus rt_get_continuous_states(Instance *inst, double x[], size_t n);
RtStatus rt_get_derivatives(Instance *inst, double dx[], size_t n);
RtStatus rt_get_event_indicators(Instance *inst, double z[], size_t n);
RtStatus rt_get_nominals(Instance *inst, double nominals[], size_t n);
size_t rt_n_states(void);
size_t rt_n_event_indicators(void);

/* FMU state: an opaque copy of phase, time, values[] and the model state. */
typedef struct RtState RtState;
RtStatus rt_get_state(Instance *inst, RtState **state);
RtStatus rt_set_state(Instance *inst, const RtState *state);
RtStatus rt_free_state(Instance *inst, RtState **state);
size_t rt_serialized_size(const Instance *inst);
RtStatus rt_serialize(Instance *inst, const RtState *state, unsigned char *buf, size_t size);
RtStatus rt_deserialize(Instance *inst, const unsigned char *buf, size_t size, RtState **state);

#endif
