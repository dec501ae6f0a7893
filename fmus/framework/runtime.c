/*
 * runtime.c - the shared, FMI-version-independent runtime (see runtime.h).
 *
 * Rules enforced here, with a logged message naming the call, the variable,
 * the value and the time:
 *   - call sequence: instantiated -> initialization -> step -> terminated,
 *     reset back to instantiated; any error moves the instance to PHASE_ERROR
 *     where only get, reset and free are accepted;
 *   - set: no outputs, fixed parameters only before/during initialization,
 *     no NaN/Inf, inputs inside [min, max] of the variable table;
 *   - parameters are range-checked (all at once) and cross-checked by the
 *     model's validate() when initialization ends;
 *   - after every step every output must be finite.
 */
#include "runtime.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MSG_MAX 1024

static const char *const PHASE_NAMES[] = {
    "instantiated", "initialization mode", "step mode", "terminated", "error"
};

struct RtState {
    Phase phase;
    double start_time;
    double time;
    double *values;
    unsigned char *state;
};

static const char *category_of(LogLevel level)
{
    switch (level) {
    case LOG_ERROR: return "logStatusError";
    case LOG_WARNING: return "logStatusWarning";
    default: return "logInfo";
    }
}

static void emit(const Instance *inst, LogLevel level, const char *category, const char *msg)
{
    if (!inst || !inst->log_fn) return;
    if (level == LOG_OK && !inst->logging_on) return;
    inst->log_fn(inst->log_env, inst->name, level, category, msg);
}

static void vlog(const Instance *inst, LogLevel level, const char *fmt, va_list ap)
{
    char msg[MSG_MAX];
    vsnprintf(msg, sizeof msg, fmt, ap);
    /* FMI2 loggers may treat the message as a printf format: no '%' in it. */
    for (char *p = msg; *p; ++p)
        if (*p == '%') *p = '?';
    emit(inst, level, category_of(level), msg);
}

void rt_log(const Instance *inst, LogLevel level, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(inst, level, fmt, ap);
    va_end(ap);
}

void model_logf(const ModelLogger *log, LogLevel level, const char *fmt, ...)
{
    char msg[MSG_MAX];
    va_list ap;
    if (!log || !log->log) return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (char *p = msg; *p; ++p)
        if (*p == '%') *p = '?';
    log->log(log->env, level, category_of(level), msg);
}

static void model_log_bridge(void *env, LogLevel level, const char *category, const char *message)
{
    emit((const Instance *)env, level, category, message);
}

static RtStatus fail(Instance *inst, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(inst, LOG_ERROR, fmt, ap);
    va_end(ap);
    inst->phase = PHASE_ERROR;
    return RT_ERROR;
}

static void load_start_values(Instance *inst)
{
    for (size_t i = 0; i < MODEL.n_variables; ++i)
        inst->values[i] = MODEL.variables[i].start;
    memset(inst->state, 0, MODEL.state_size);
    inst->start_time = 0.0;
    inst->time = 0.0;
    inst->phase = PHASE_INSTANTIATED;
}

Instance *rt_instantiate(const char *name, const char *token,
                         RtLogFn log_fn, void *log_env, int logging_on)
{
    Instance tmp = {0};
    tmp.name = (char *)(name ? name : "?");
    tmp.log_fn = log_fn;
    tmp.log_env = log_env;
    if (!token || strcmp(token, MODEL.guid) != 0) {
        rt_log(&tmp, LOG_ERROR, "instantiate: token/guid '%s' does not match %s's '%s'",
               token ? token : "(null)", MODEL.identifier, MODEL.guid);
        return NULL;
    }
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    *inst = tmp;
    inst->name = malloc(strlen(tmp.name) + 1);
    inst->values = calloc(MODEL.n_variables ? MODEL.n_variables : 1, sizeof(double));
    inst->state = calloc(1, MODEL.state_size ? MODEL.state_size : 1);
    if (!inst->name || !inst->values || !inst->state) {
        rt_log(&tmp, LOG_ERROR, "instantiate: out of memory");
        rt_free(inst);
        return NULL;
    }
    strcpy(inst->name, tmp.name);
    inst->logging_on = logging_on;
    inst->model_logger.env = inst;
    inst->model_logger.log = model_log_bridge;
    load_start_values(inst);
    return inst;
}

void rt_free(Instance *inst)
{
    if (!inst) return;
    free(inst->name);
    free(inst->values);
    free(inst->state);
    free(inst);
}

RtStatus rt_set_logging(Instance *inst, int on)
{
    inst->logging_on = on;
    return RT_OK;
}

static RtStatus require_phase(Instance *inst, const char *call, unsigned mask)
{
    if (mask & (1u << inst->phase)) return RT_OK;
    if (inst->phase == PHASE_INSTANTIATED && call[0] == 'd')
        return fail(inst, "%s called before initialization (phase '%s'): call "
                    "enterInitializationMode and exitInitializationMode first",
                    call, PHASE_NAMES[inst->phase]);
    return fail(inst, "%s is not allowed in phase '%s'", call, PHASE_NAMES[inst->phase]);
}

#define IN(p) (1u << (p))

RtStatus rt_setup_experiment(Instance *inst, double start_time)
{
    if (require_phase(inst, "setupExperiment", IN(PHASE_INSTANTIATED))) return RT_ERROR;
    if (!isfinite(start_time))
        return fail(inst, "setupExperiment: start time %g is not finite", start_time);
    inst->start_time = start_time;
    inst->time = start_time;
    return RT_OK;
}

RtStatus rt_enter_initialization(Instance *inst)
{
    if (require_phase(inst, "enterInitializationMode", IN(PHASE_INSTANTIATED))) return RT_ERROR;
    inst->phase = PHASE_INIT;
    return RT_OK;
}

/* Check every parameter and input against its range; log each offender. */
static int count_out_of_range(Instance *inst)
{
    int bad = 0;
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        double x = inst->values[i];
        if (v->causality == CAUSALITY_OUTPUT) continue;
        if (!(x >= v->min && x <= v->max)) {
            rt_log(inst, LOG_ERROR, "%s %s = %g is outside its valid range [%g, %g] (%s)",
                   v->causality == CAUSALITY_PARAMETER ? "parameter" : "input",
                   v->name, x, v->min, v->max, v->description);
            ++bad;
        }
    }
    return bad;
}

/* Validate parameters and compute the initial outputs. */
static RtStatus compute_initial(Instance *inst, const char *call)
{
    int bad = count_out_of_range(inst);
    if (bad)
        return fail(inst, "%s: %d variable(s) of %s out of range (see above)",
                    call, bad, MODEL.identifier);
    if (MODEL.validate && MODEL.validate(inst->values, &inst->model_logger) != MODEL_OK)
        return fail(inst, "%s: %s rejected its parameters (see above)", call, MODEL.identifier);
    memset(inst->state, 0, MODEL.state_size);
    if (MODEL.initialize(inst->values, inst->state, inst->start_time,
                         &inst->model_logger) != MODEL_OK)
        return fail(inst, "%s: %s failed to initialize (see above)", call, MODEL.identifier);
    return RT_OK;
}

RtStatus rt_exit_initialization(Instance *inst)
{
    if (require_phase(inst, "exitInitializationMode", IN(PHASE_INIT))) return RT_ERROR;
    if (compute_initial(inst, "exitInitializationMode")) return RT_ERROR;
    inst->time = inst->start_time;
    inst->phase = PHASE_STEP;
    rt_log(inst, LOG_OK, "%s initialized at t = %g", MODEL.identifier, inst->start_time);
    return RT_OK;
}

static RtStatus check_outputs_finite(Instance *inst, double t)
{
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        if (v->causality == CAUSALITY_OUTPUT && !isfinite(inst->values[i]))
            return fail(inst, "doStep: %s output %s = %g is not finite at t = %.9g",
                        MODEL.identifier, v->name, inst->values[i], t);
    }
    return RT_OK;
}

RtStatus rt_do_step(Instance *inst, double t, double h)
{
    if (require_phase(inst, "doStep", IN(PHASE_STEP))) return RT_ERROR;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0))
        return fail(inst, "doStep: invalid communication point %g or step size %g (must be > 0)", t, h);
    if (fabs(t - inst->time) > 1e-9 * fmax(1.0, fabs(t)))
        return fail(inst, "doStep: communication point %.17g differs from the FMU time %.17g",
                    t, inst->time);
    if (MODEL.do_step(inst->values, inst->state, t, h, &inst->model_logger) != MODEL_OK)
        return fail(inst, "doStep: %s failed at t = %.9g (see above)", MODEL.identifier, t);
    if (check_outputs_finite(inst, t + h)) return RT_ERROR;
    inst->time = t + h;
    return RT_OK;
}

RtStatus rt_terminate(Instance *inst)
{
    if (require_phase(inst, "terminate", IN(PHASE_INIT) | IN(PHASE_STEP))) return RT_ERROR;
    inst->phase = PHASE_TERMINATED;
    return RT_OK;
}

RtStatus rt_reset(Instance *inst)
{
    load_start_values(inst);
    rt_log(inst, LOG_OK, "%s reset to its start values", MODEL.identifier);
    return RT_OK;
}

static int wants_output(const unsigned int vr[], size_t n)
{
    for (size_t i = 0; i < n; ++i)
        if (vr[i] < MODEL.n_variables && MODEL.variables[vr[i]].causality == CAUSALITY_OUTPUT)
            return 1;
    return 0;
}

RtStatus rt_get_float64(Instance *inst, const unsigned int vr[], size_t n, double out[])
{
    unsigned mask = IN(PHASE_INIT) | IN(PHASE_STEP) | IN(PHASE_TERMINATED) | IN(PHASE_ERROR);
    if (require_phase(inst, "getFloat64/getReal", mask)) return RT_ERROR;
    if (inst->phase == PHASE_INIT && wants_output(vr, n)) {
        if (compute_initial(inst, "getting outputs in initialization mode")) return RT_ERROR;
    }
    for (size_t i = 0; i < n; ++i) {
        if (vr[i] == RT_VR_TIME) out[i] = inst->time;
        else if (vr[i] < MODEL.n_variables) out[i] = inst->values[vr[i]];
        else return fail(inst, "get: unknown value reference %u (%s has %u variables)",
                         vr[i], MODEL.identifier, (unsigned)MODEL.n_variables);
    }
    return RT_OK;
}

/* A tunable parameter changed in step mode: range and cross-checks at once. */
static RtStatus set_tunable(Instance *inst, unsigned int vr, double x)
{
    const VariableInfo *v = &MODEL.variables[vr];
    double old = inst->values[vr];
    if (!(x >= v->min && x <= v->max))
        return fail(inst, "set: parameter %s = %g is outside its valid range [%g, %g] at t = %.9g",
                    v->name, x, v->min, v->max, inst->time);
    inst->values[vr] = x;
    if (MODEL.validate && MODEL.validate(inst->values, &inst->model_logger) != MODEL_OK) {
        inst->values[vr] = old;
        return fail(inst, "set: %s rejected parameter %s = %g at t = %.9g (see above)",
                    MODEL.identifier, v->name, x, inst->time);
    }
    return RT_OK;
}

static RtStatus set_one(Instance *inst, unsigned int vr, double x)
{
    if (vr >= MODEL.n_variables)
        return fail(inst, "set: unknown or read-only value reference %u", vr);
    const VariableInfo *v = &MODEL.variables[vr];
    if (v->causality == CAUSALITY_OUTPUT)
        return fail(inst, "set: %s is an output and cannot be set", v->name);
    if (v->causality == CAUSALITY_PARAMETER && v->variability == VARIABILITY_FIXED
        && inst->phase == PHASE_STEP)
        return fail(inst, "set: fixed parameter %s can only be set before initialization ends", v->name);
    if (!isfinite(x))
        return fail(inst, "set: %s = %g is not finite (t = %.9g)", v->name, x, inst->time);
    if (v->causality == CAUSALITY_INPUT && !(x >= v->min && x <= v->max))
        return fail(inst, "set: input %s = %g is outside its valid range [%g, %g] at t = %.9g",
                    v->name, x, v->min, v->max, inst->time);
    if (v->causality == CAUSALITY_PARAMETER && inst->phase == PHASE_STEP)
        return set_tunable(inst, vr, x);
    inst->values[vr] = x;
    return RT_OK;
}

RtStatus rt_set_float64(Instance *inst, const unsigned int vr[], size_t n, const double in[])
{
    unsigned mask = IN(PHASE_INSTANTIATED) | IN(PHASE_INIT) | IN(PHASE_STEP);
    if (require_phase(inst, "setFloat64/setReal", mask)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i)
        if (set_one(inst, vr[i], in[i])) return RT_ERROR;
    return RT_OK;
}

RtStatus rt_no_such_type(Instance *inst, const char *function, size_t n)
{
    if (n == 0) return RT_OK;
    return fail(inst, "%s: %s has only Float64 (Real) variables", function, MODEL.identifier);
}

RtStatus rt_unsupported(Instance *inst, const char *function)
{
    if (!inst) return RT_ERROR;
    return fail(inst, "%s is not supported by %s (co-simulation only)", function, MODEL.identifier);
}

/* ---- FMU state ---------------------------------------------------------- */

static RtState *state_alloc(void)
{
    RtState *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->values = calloc(MODEL.n_variables ? MODEL.n_variables : 1, sizeof(double));
    s->state = calloc(1, MODEL.state_size ? MODEL.state_size : 1);
    if (!s->values || !s->state) {
        free(s->values);
        free(s->state);
        free(s);
        return NULL;
    }
    return s;
}

static void state_copy(Phase *phase, double *t0, double *t, double *values, void *state,
                       Phase sphase, double st0, double st, const double *svalues,
                       const void *sstate)
{
    *phase = sphase;
    *t0 = st0;
    *t = st;
    memcpy(values, svalues, MODEL.n_variables * sizeof(double));
    memcpy(state, sstate, MODEL.state_size);
}

RtStatus rt_get_state(Instance *inst, RtState **state)
{
    if (!state) return fail(inst, "getFMUState: null pointer");
    if (!*state) *state = state_alloc();
    if (!*state) return fail(inst, "getFMUState: out of memory");
    RtState *s = *state;
    state_copy(&s->phase, &s->start_time, &s->time, s->values, s->state,
               inst->phase, inst->start_time, inst->time, inst->values, inst->state);
    return RT_OK;
}

RtStatus rt_set_state(Instance *inst, const RtState *s)
{
    if (!s) return fail(inst, "setFMUState: null state");
    state_copy(&inst->phase, &inst->start_time, &inst->time, inst->values, inst->state,
               s->phase, s->start_time, s->time, s->values, s->state);
    return RT_OK;
}

RtStatus rt_free_state(Instance *inst, RtState **state)
{
    (void)inst;
    if (state && *state) {
        free((*state)->values);
        free((*state)->state);
        free(*state);
        *state = NULL;
    }
    return RT_OK;
}

/* Layout: guid '\0' | int32 phase | double start_time, time | values | state. */
size_t rt_serialized_size(const Instance *inst)
{
    (void)inst;
    return strlen(MODEL.guid) + 1 + sizeof(int32_t) + 2 * sizeof(double)
           + MODEL.n_variables * sizeof(double) + MODEL.state_size;
}

RtStatus rt_serialize(Instance *inst, const RtState *s, unsigned char *buf, size_t size)
{
    size_t need = rt_serialized_size(inst), g = strlen(MODEL.guid) + 1;
    if (!s || !buf || size < need)
        return fail(inst, "serializeFMUState: buffer of %u bytes, %u needed",
                    (unsigned)size, (unsigned)need);
    int32_t phase = (int32_t)s->phase;
    memcpy(buf, MODEL.guid, g); buf += g;
    memcpy(buf, &phase, sizeof phase); buf += sizeof phase;
    memcpy(buf, &s->start_time, sizeof(double)); buf += sizeof(double);
    memcpy(buf, &s->time, sizeof(double)); buf += sizeof(double);
    memcpy(buf, s->values, MODEL.n_variables * sizeof(double));
    buf += MODEL.n_variables * sizeof(double);
    memcpy(buf, s->state, MODEL.state_size);
    return RT_OK;
}

RtStatus rt_deserialize(Instance *inst, const unsigned char *buf, size_t size, RtState **state)
{
    size_t g = strlen(MODEL.guid) + 1;
    int32_t phase;
    if (!buf || size != rt_serialized_size(inst) || memcmp(buf, MODEL.guid, g) != 0)
        return fail(inst, "deserializeFMUState: %u bytes are not a serialized %s state",
                    (unsigned)size, MODEL.identifier);
    memcpy(&phase, buf + g, sizeof phase);
    if (phase < PHASE_INSTANTIATED || phase > PHASE_ERROR)
        return fail(inst, "deserializeFMUState: corrupt phase %d", (int)phase);
    if (!state) return fail(inst, "deserializeFMUState: null pointer");
    if (!*state) *state = state_alloc();
    if (!*state) return fail(inst, "deserializeFMUState: out of memory");
    RtState *s = *state;
    buf += g + sizeof phase;
    s->phase = (Phase)phase;
    memcpy(&s->start_time, buf, sizeof(double)); buf += sizeof(double);
    memcpy(&s->time, buf, sizeof(double)); buf += sizeof(double);
    memcpy(s->values, buf, MODEL.n_variables * sizeof(double));
    buf += MODEL.n_variables * sizeof(double);
    memcpy(s->state, buf, MODEL.state_size);
    return RT_OK;
}
