/*
 * LagME: y' = (gain * u - y) / tau, exact for u held over a step:
 *   y(t + h) = K u + (y(t) - K u) exp(-h / tau).
 * No event indicator and no time event: the master's input events (a changed
 * u at a tick) are the only events. do_step is NULL: co-simulation runs the
 * framework's RK4 integrator.
 */
#include <math.h>
#include <stddef.h>

#include "model.h"
#include "variable_table.h"

static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
};

static const unsigned STATES[] = {VR_y};
static const unsigned DERIVATIVES[] = {VR_der_y};

static ModelStatus validate(const double *values, const ModelLogger *log)
{
    if (!(values[VR_tau] > 0.0)) {
        model_logf(log, LOG_ERROR, "LagME: tau must be > 0, got %g", values[VR_tau]);
        return MODEL_ERROR;
    }
    return MODEL_OK;
}

static ModelStatus initialize(double *values, void *state, double t0, const ModelLogger *log)
{
    (void)state; (void)t0; (void)log;
    values[VR_y] = values[VR_y0];
    return MODEL_OK;
}

static ModelStatus evaluate(double *values, void *state, double t, const ModelLogger *log)
{
    (void)state; (void)t; (void)log;
    values[VR_der_y] = (values[VR_gain] * values[VR_u] - values[VR_y]) / values[VR_tau];
    return MODEL_OK;
}

static ModelStatus event_update(double *values, void *state, double t, ModelEvent *event,
                                const ModelLogger *log)
{
    (void)values; (void)state; (void)t; (void)log;
    event->next_event_time = INFINITY;
    return MODEL_OK;
}

const ModelDefinition MODEL = {
    "LagME",
    "{9d0c3a51-7b2e-4f3a-8c1d-1a9e0f7a0002}",
    "First-order lag, Model Exchange (and co-simulation)",
    VARIABLES,
    sizeof VARIABLES / sizeof VARIABLES[0],
    0,
    0.01,
    validate,
    initialize,
    NULL,
};

const ModelExtension MODEL_EXTENSION = {
    0u,
    1, STATES, DERIVATIVES,
    0, NULL,
    evaluate,
    event_update,
    0.01,
};
