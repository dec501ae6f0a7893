/*
 * model.h - the contract between the shared FMI runtime and per-model code.
 *
 * Three layers (DESIGN.md, Style):
 *   1. fmi2_api.c / fmi3_api.c : the FMI API functions, thin, no model code;
 *   2. runtime.c               : instance life cycle, call-sequence checks,
 *                                logging, value storage, FMU state save/restore;
 *   3. <Model>/model.c         : the variable table and the equations.
 *
 * A model folder provides:
 *   - variables.def : the variable table, one X-macro line per variable:
 *       VAR(ident, causality, variability, unit, start, min, max, "description")
 *     for a Float64 (FMI2 Real) variable, or
 *       TVAR(type, ident, causality, variability, unit, start, min, max, "description")
 *     for any type of VarType below (FLOAT64, FLOAT32, INT8 ... UINT64, BOOLEAN).
 *     causality   : PARAMETER | INPUT | OUTPUT | LOCAL
 *     variability : FIXED | TUNABLE (parameters) | CONTINUOUS (Float only) |
 *                   DISCRETE (changes only at steps or events; required for
 *                   integer and Boolean inputs, outputs and locals)
 *     Integer and Boolean variables have no unit: write "". Boolean: start 0
 *     or 1, min 0, max 1. FMI 2.0 has only Real, Integer and Boolean: FLOAT32
 *     becomes Real, INT8..INT32/UINT8/UINT16 become Integer, and UINT32, INT64,
 *     UINT64 are FMI 3.0 only (the FMI 2.0 build rejects them).
 *     The order of lines gives the value references (0, 1, 2, ...). The table is
 *     the single source of the C enum below, the units, and both
 *     modelDescription.xml files (generated from it at build time).
 *   - model.c : defines `const ModelDefinition MODEL` and the functions it
 *     points to, plus `#define MODEL_IDENTIFIER` via the build (-D); optionally
 *     `const ModelExtension MODEL_EXTENSION` (Model Exchange, flags; below).
 *
 * Values of every type live in `values[]` (doubles), indexed by value
 * reference: integers and Booleans are stored exactly (Int64/UInt64 only up to
 * 2^53, larger values are rejected), Float32 values are rounded to float. After
 * every step or evaluation the runtime checks that each non-Float64 output and
 * local holds a value of its type (integral, in range, 0/1 for Booleans). The
 * model's private state lives in a plain-data struct of `state_size` bytes
 * that the runtime allocates, zeroes, copies for get/set FMU state, and never
 * interprets.
 */
#ifndef COSIM_MODEL_H
#define COSIM_MODEL_H

#include <stddef.h>

typedef enum { CAUSALITY_PARAMETER, CAUSALITY_INPUT, CAUSALITY_OUTPUT, CAUSALITY_LOCAL } Causality;
typedef enum {
    VARIABILITY_FIXED, VARIABILITY_TUNABLE, VARIABILITY_CONTINUOUS, VARIABILITY_DISCRETE
} Variability;
/* Variable types (FMI 3.0 names); TYPE_FLOAT64 is FMI 2.0 Real. */
typedef enum {
    TYPE_FLOAT64, TYPE_FLOAT32, TYPE_INT8, TYPE_UINT8, TYPE_INT16, TYPE_UINT16,
    TYPE_INT32, TYPE_UINT32, TYPE_INT64, TYPE_UINT64, TYPE_BOOLEAN, TYPE_COUNT
} VarType;

typedef struct {
    const char *name;        /* canonical name, e.g. "delta" */
    Causality causality;
    Variability variability;
    const char *unit;        /* SI unit string, "1" for dimensionless */
    double start;
    double min;              /* valid range, checked for parameters and inputs */
    double max;
    const char *description;
    VarType type;            /* TYPE_FLOAT64 for VAR(...) lines */
} VariableInfo;

typedef enum { LOG_OK, LOG_WARNING, LOG_ERROR } LogLevel;

/* Logging into the importer's logger; the runtime supplies the implementation. */
typedef struct ModelLogger {
    void *env;
    void (*log)(void *env, LogLevel level, const char *category, const char *message);
} ModelLogger;

/* Result of a model call: 0 = ok, non-zero = error (already logged by the model).
   do_step (and event_update) may also return MODEL_WARNING (done, warnings
   logged), MODEL_FATAL (the instance is unusable: FMI Fatal) or MODEL_TERMINATE
   (done, and the model asks the importer to end the simulation: FMI2 Discard
   with fmi2Terminated = true, FMI3 terminateSimulation = true). Other callbacks
   treat every non-zero value as an error. */
typedef int ModelStatus;
#define MODEL_OK 0
#define MODEL_ERROR 1
#define MODEL_WARNING 2
#define MODEL_FATAL 3
#define MODEL_TERMINATE 4

typedef struct {
    const char *identifier;   /* modelIdentifier, also the FMU file stem */
    const char *guid;         /* FMI2 guid / FMI3 instantiationToken */
    const char *description;
    const VariableInfo *variables;
    size_t n_variables;
    size_t state_size;        /* bytes of the model's private POD state */
    double default_step;      /* suggested communication step, s */

    /* Check parameter values (ranges done by the runtime; this is for
       cross-parameter rules). Called at exitInitializationMode. */
    ModelStatus (*validate)(const double *values, const ModelLogger *log);
    /* Set the private state from parameters/initial values and compute
       the outputs at the start time. */
    ModelStatus (*initialize)(double *values, void *state, double t0, const ModelLogger *log);
    /* Advance from t to t + h with inputs held constant; update outputs. */
    ModelStatus (*do_step)(double *values, void *state, double t, double h, const ModelLogger *log);
} ModelDefinition;

extern const ModelDefinition MODEL;

/* ---- Optional: Model Exchange and capability flags ------------------------
 * A model that defines `const ModelExtension MODEL_EXTENSION = {...};` gets
 * the capabilities it describes; a model without it is co-simulation only
 * (the symbol is weak: absent means NULL).
 *
 * Model Exchange: the continuous states, their derivatives and the event
 * indicators are ordinary variables of the table (states usually OUTPUT or
 * LOCAL, derivatives and indicators LOCAL, all Float64 CONTINUOUS); the
 * extension lists their value references. `evaluate` computes, from the states,
 * inputs and parameters in values[] at time t, every derivative, indicator and
 * output; the runtime calls it lazily, whenever one of them is read after a
 * change of time, states or inputs. `event_update` handles an event at time t
 * (state event: an indicator changed sign; time event: t reached the
 * next_event_time it reported before; or the first event iteration after
 * initialization): it may change states and discrete variables and fills
 * ModelEvent. It is called with ModelEvent zeroed and next_event_time =
 * INFINITY (no time event). Event indicators follow FMI: an event happens when
 * one goes from > 0 to <= 0 or from < 0 to >= 0.
 *
 * Co-simulation of a Model Exchange model: if MODEL.do_step is NULL, the
 * runtime integrates it with classical Runge-Kutta 4 in sub-steps of at most
 * cs_max_step, locates state events by bisection (to ~1e-12 s), stops at time
 * events, and runs the event iteration there.
 */
typedef struct {
    int states_changed;      /* out: event_update changed continuous states */
    int needs_update;        /* out: call event_update again at the same time */
    int terminate;           /* out: the model asks to end the simulation */
    double next_event_time;  /* out: next time event, INFINITY if none */
} ModelEvent;

#define MODEL_FLAG_ONE_INSTANCE_PER_PROCESS 1u  /* canBeInstantiatedOnlyOncePerProcess */
#define MODEL_FLAG_NO_COSIMULATION          2u  /* Model Exchange only */

typedef struct {
    unsigned flags;                  /* MODEL_FLAG_* */
    size_t n_states;
    const unsigned *state_vrs;       /* value reference of each continuous state */
    const unsigned *derivative_vrs;  /* value reference of its time derivative */
    size_t n_event_indicators;
    const unsigned *indicator_vrs;   /* value reference of each event indicator */
    /* NULL: no Model Exchange */
    ModelStatus (*evaluate)(double *values, void *state, double t, const ModelLogger *log);
    ModelStatus (*event_update)(double *values, void *state, double t, ModelEvent *event,
                                const ModelLogger *log);
    double cs_max_step;              /* co-simulation sub-step (do_step NULL), s */
} ModelExtension;

extern const ModelExtension MODEL_EXTENSION __attribute__((weak, visibility("hidden")));

/* Helper for model code: log an error with printf-style formatting. */
void model_logf(const ModelLogger *log, LogLevel level, const char *fmt, ...);

#endif
