/*
 * Lag model: exact solution of y' = (K u - y) / tau over a step with u held:
 *   y(t + h) = K u + (y(t) - K u) exp(-h / tau).
 * Test-only FMU for the co-simulation master (tests/fmu/test_host.py).
 */
#include <math.h>
#include <string.h>

#include "model.h"
#include "variable_table.h"

static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
};

typedef struct {
    double y;
} LagState;

static ModelStatus validate(const double *values, const ModelLogger *log)
{
    if (!(values[VR_tau] > 0.0)) {
        model_logf(log, LOG_ERROR, "Lag: tau must be > 0, got %g", values[VR_tau]);
        return MODEL_ERROR;
    }
    return MODEL_OK;
}

static ModelStatus initialize(double *values, void *state, double t0, const ModelLogger *log)
{
    LagState *st = state;
    (void)t0; (void)log;
    st->y = values[VR_y_init];
    values[VR_y_out] = st->y;
    return MODEL_OK;
}

static ModelStatus do_step(double *values, void *state, double t, double h, const ModelLogger *log)
{
    LagState *st = state;
    double target = values[VR_gain] * values[VR_u_cmd];
    (void)t; (void)log;
    st->y = target + (st->y - target) * exp(-h / values[VR_tau]);
    values[VR_y_out] = st->y;
    return MODEL_OK;
}

const ModelDefinition MODEL = {
    "Lag",
    "{9d0c3a51-7b2e-4f3a-8c1d-1a9e0f7a0001}",
    "First-order lag, a test FMU that is not a vehicle",
    VARIABLES,
    sizeof VARIABLES / sizeof VARIABLES[0],
    sizeof(LagState),
    0.01,
    validate,
    initialize,
    do_step,
};
