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
 *     causality   : PARAMETER | INPUT | OUTPUT
 *     variability : FIXED (parameters set before init) | TUNABLE | CONTINUOUS
 *     The order of lines gives the value references (0, 1, 2, ...). The table is
 *     the single source of the C enum below, the units, and both
 *     modelDescription.xml files (generated from it at build time).
 *   - model.c : defines `const ModelDefinition MODEL` and the functions it
 *     points to, plus `#define MODEL_IDENTIFIER` via the build (-D).
 *
 * All variables are Float64 (FMI2 Real). Values live in `values[]`, indexed by
 * value reference; the model's private continuous state lives in a plain-data
 * struct of `state_size` bytes that the runtime allocates, zeroes, copies for
 * get/set FMU state, and never interprets.
 */
#ifndef COSIM_MODEL_H
#define COSIM_MODEL_H

#include <stddef.h>

typedef enum { CAUSALITY_PARAMETER, CAUSALITY_INPUT, CAUSALITY_OUTPUT } Causality;
typedef enum { VARIABILITY_FIXED, VARIABILITY_TUNABLE, VARIABILITY_CONTINUOUS } Variability;

typedef struct {
    const char *name;        /* canonical name, e.g. "delta" */
    Causality causality;
    Variability variability;
    const char *unit;        /* SI unit string, "1" for dimensionless */
    double start;
    double min;              /* valid range, checked for parameters and inputs */
    double max;
    const char *description;
} VariableInfo;

typedef enum { LOG_OK, LOG_WARNING, LOG_ERROR } LogLevel;

/* Logging into the importer's logger; the runtime supplies the implementation. */
typedef struct ModelLogger {
    void *env;
    void (*log)(void *env, LogLevel level, const char *category, const char *message);
} ModelLogger;

/* Result of a model call: 0 = ok, non-zero = error (already logged by the model). */
typedef int ModelStatus;
#define MODEL_OK 0
#define MODEL_ERROR 1

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

/* Helper for model code: log an error with printf-style formatting. */
void model_logf(const ModelLogger *log, LogLevel level, const char *fmt, ...);

#endif
