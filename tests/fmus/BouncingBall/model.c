/*
 * BouncingBall: a test-only Model Exchange FMU (FMI 2.0 and 3.0) for the
 * framework's Model Exchange support, with analytic event times.
 *
 *   der(h) = v, der(v) = -g            in flight
 *   state event z_floor = h crosses 0 with v < 0:
 *       v := -e v, h := 0, bounces += 1; if the rebound speed e|v| < v_min the
 *       ball comes to rest (h = v = 0, der = 0, z_floor = 1, resting = true)
 *   time event at t_kick: v := v + v_kick (a resting ball leaves the floor if
 *       the result is upward), kicked = true
 *
 * So with h0 = 1 m, v0 = 0, g = 9.81, e = 0.7, v_min = 1 m/s the impacts are at
 * t1 = sqrt(2 h0 / g) and t(k+1) = t(k) + 2 e^k v1 / g (v1 = g t1): 0.4515,
 * 1.0837, 1.5261, 1.8359, 2.0526 s; the ball rests at the 5th impact (rebound
 * 0.74 m/s < 1 m/s), the kick at 3 s throws it up at 4 m/s, and it lands again
 * at 3.8155, 4.3863, 4.7859 s.
 *
 * do_step is NULL: co-simulation uses the framework's RK4 integrator with
 * event location (exact for this piecewise-parabolic motion up to the 1e-12 s
 * bisection). variant.h selects the identifier and flags (BouncingBallME:
 * Model Exchange only).
 */
#include <math.h>
#include <stddef.h>

#include "model.h"
#include "variable_table.h"
#include "variant.h"

static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#define TVAR MODEL_TYPED_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
#undef TVAR
};

static const unsigned STATES[] = {VR_h, VR_v};
static const unsigned DERIVATIVES[] = {VR_der_h, VR_der_v};
static const unsigned INDICATORS[] = {VR_z_floor};

static ModelStatus validate(const double *values, const ModelLogger *log)
{
    if (!(values[VR_g] > 0.0)) {
        model_logf(log, LOG_ERROR, "BouncingBall: g must be > 0, got %g", values[VR_g]);
        return MODEL_ERROR;
    }
    return MODEL_OK;
}

static ModelStatus initialize(double *values, void *state, double t0, const ModelLogger *log)
{
    (void)state; (void)t0; (void)log;
    values[VR_h] = values[VR_h0];
    values[VR_v] = values[VR_v0];
    values[VR_bounces] = 0.0;
    values[VR_resting] = values[VR_h0] == 0.0 && values[VR_v0] == 0.0;
    values[VR_kicked] = 0.0;
    return MODEL_OK;
}

static ModelStatus evaluate(double *values, void *state, double t, const ModelLogger *log)
{
    int resting = values[VR_resting] != 0.0;
    (void)state; (void)t; (void)log;
    values[VR_der_h] = resting ? 0.0 : values[VR_v];
    values[VR_der_v] = resting ? 0.0 : -values[VR_g];
    values[VR_z_floor] = resting ? 1.0 : values[VR_h];
    return MODEL_OK;
}

static ModelStatus event_update(double *values, void *state, double t, ModelEvent *event,
                                const ModelLogger *log)
{
    double t_kick = values[VR_t_kick];
    (void)state;
    if (values[VR_kicked] == 0.0 && t >= t_kick - 1e-12 * fmax(1.0, fabs(t_kick))) {
        values[VR_v] += values[VR_v_kick];
        values[VR_kicked] = 1.0;
        if (values[VR_resting] != 0.0) {
            if (values[VR_v] > 0.0) values[VR_resting] = 0.0;
            else values[VR_v] = 0.0;
        }
        event->states_changed = 1;
        model_logf(log, LOG_OK, "BouncingBall: kick at t = %.9g, v = %g", t, values[VR_v]);
    }
    if (values[VR_resting] == 0.0 && values[VR_h] <= 0.0 && values[VR_v] < 0.0) {
        values[VR_bounces] += 1.0;
        values[VR_h] = 0.0;
        values[VR_v] = -values[VR_e] * values[VR_v];
        if (values[VR_v] < values[VR_v_min]) {
            values[VR_v] = 0.0;
            values[VR_resting] = 1.0;
        }
        event->states_changed = 1;
        model_logf(log, LOG_OK, "BouncingBall: impact %g at t = %.9g, rebound v = %g",
                   values[VR_bounces], t, values[VR_v]);
    }
    event->next_event_time = values[VR_kicked] != 0.0 ? INFINITY : t_kick;
    return MODEL_OK;
}

const ModelDefinition MODEL = {
    BALL_IDENTIFIER,
    BALL_GUID,
    BALL_DESCRIPTION,
    VARIABLES,
    sizeof VARIABLES / sizeof VARIABLES[0],
    0,
    0.01,
    validate,
    initialize,
    NULL,  /* co-simulation: the framework integrates evaluate() */
};

const ModelExtension MODEL_EXTENSION = {
    BALL_FLAGS,
    2, STATES, DERIVATIVES,
    1, INDICATORS,
    evaluate,
    event_update,
    0.01,
};
