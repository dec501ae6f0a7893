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
 *   - after every step every output must be finite, and every non-Float64
 *     output or local a value of its type;
 *   - typed get/set: the API function's type must be the variable's type.
 * Model Exchange (MODEL_EXTENSION with evaluate) adds event and continuous-time
 * modes with lazy evaluation; a Model Exchange model without do_step is
 * co-simulated by the RK4 integrator with event location at the end of file.
 */
#include "runtime.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MSG_MAX 1024

static const char *const PHASE_NAMES[PHASE_COUNT] = {
    "instantiated", "initialization mode", "step mode", "terminated", "error",
    "event mode", "continuous-time mode"
};

#define EXT (&MODEL_EXTENSION)
#define HAS_EXT (&MODEL_EXTENSION != NULL)

struct RtState {
    Phase phase;
    double start_time;
    double time;
    int flags;               /* terminate_requested | dirty << 1 */
    double next_event_time;
    double *values;
    unsigned char *state;
};

static int live_instances;   /* for MODEL_FLAG_ONE_INSTANCE_PER_PROCESS */

static const struct {
    const char *name;
    double lo, hi;
} TYPES[TYPE_COUNT] = {
    {"Float64", -DBL_MAX, DBL_MAX},  {"Float32", -FLT_MAX, FLT_MAX},
    {"Int8", -128.0, 127.0},         {"UInt8", 0.0, 255.0},
    {"Int16", -32768.0, 32767.0},    {"UInt16", 0.0, 65535.0},
    {"Int32", -2147483648.0, 2147483647.0}, {"UInt32", 0.0, 4294967295.0},
    /* stored in doubles: exact integers only up to 2^53 */
    {"Int64", -9007199254740992.0, 9007199254740992.0}, {"UInt64", 0.0, 9007199254740992.0},
    {"Boolean", 0.0, 1.0},
};

const char *rt_type_name(VarType type)
{
    return type < TYPE_COUNT ? TYPES[type].name : "?";
}

int rt_value_fits(VarType type, double x)
{
    if (type >= TYPE_COUNT || !(x >= TYPES[type].lo && x <= TYPES[type].hi)) return 0;
    if (type == TYPE_FLOAT64 || type == TYPE_FLOAT32) return 1;
    if (type == TYPE_BOOLEAN) return x == 0.0 || x == 1.0;
    return x == floor(x);
}

int rt_has_model_exchange(void)
{
    return HAS_EXT && EXT->evaluate != NULL;
}

/* The runtime integrates the Model Exchange equations for co-simulation. */
static int integrated_cs(void)
{
    return MODEL.do_step == NULL && rt_has_model_exchange();
}

int rt_has_cosimulation(void)
{
    if (HAS_EXT && (EXT->flags & MODEL_FLAG_NO_COSIMULATION)) return 0;
    return MODEL.do_step != NULL || rt_has_model_exchange();
}

size_t rt_n_states(void)
{
    return rt_has_model_exchange() ? EXT->n_states : 0;
}

size_t rt_n_event_indicators(void)
{
    return rt_has_model_exchange() ? EXT->n_event_indicators : 0;
}

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
    inst->terminate_requested = 0;
    inst->dirty = 0;
    inst->next_event_time = INFINITY;
}

Instance *rt_instantiate(const char *name, const char *token, RtInterface interface,
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
    if (interface == RT_MODEL_EXCHANGE && !rt_has_model_exchange()) {
        rt_log(&tmp, LOG_ERROR, "instantiate: %s does not support Model Exchange "
               "(co-simulation only)", MODEL.identifier);
        return NULL;
    }
    if (interface == RT_COSIMULATION && !rt_has_cosimulation()) {
        rt_log(&tmp, LOG_ERROR, "instantiate: %s does not support co-simulation "
               "(Model Exchange only)", MODEL.identifier);
        return NULL;
    }
    if (HAS_EXT && (EXT->flags & MODEL_FLAG_ONE_INSTANCE_PER_PROCESS) && live_instances > 0) {
        rt_log(&tmp, LOG_ERROR, "instantiate: %s can be instantiated only once per process "
               "(canBeInstantiatedOnlyOncePerProcess=\"true\") and %d instance(s) exist",
               MODEL.identifier, live_instances);
        return NULL;
    }
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    *inst = tmp;
    ++live_instances;
    inst->interface = interface;
    inst->name = malloc(strlen(tmp.name) + 1);
    inst->values = calloc(MODEL.n_variables ? MODEL.n_variables : 1, sizeof(double));
    inst->state = calloc(1, MODEL.state_size ? MODEL.state_size : 1);
    /* integrator scratch: x0, k1..k4, x (states); z0, z (indicators) */
    inst->work = calloc(6 * rt_n_states() + 2 * rt_n_event_indicators() + 1, sizeof(double));
    if (!inst->name || !inst->values || !inst->state || !inst->work) {
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
    --live_instances;
    free(inst->name);
    free(inst->values);
    free(inst->state);
    free(inst->work);
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
/* Phases after initialization (co-simulation step mode or Model Exchange modes). */
#define RUNNING (IN(PHASE_STEP) | IN(PHASE_EVENT) | IN(PHASE_CONTINUOUS))

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
        if (v->causality == CAUSALITY_OUTPUT || v->causality == CAUSALITY_LOCAL) continue;
        if (!(x >= v->min && x <= v->max)) {
            rt_log(inst, LOG_ERROR, "%s %s = %g is outside its valid range [%g, %g] (%s)",
                   v->causality == CAUSALITY_PARAMETER ? "parameter" : "input",
                   v->name, x, v->min, v->max, v->description);
            ++bad;
        }
    }
    return bad;
}

/* After a model computation: every output and local finite and of its type. */
static RtStatus check_outputs(Instance *inst, const char *call, double t)
{
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        double x = inst->values[i];
        if (v->causality != CAUSALITY_OUTPUT && v->causality != CAUSALITY_LOCAL) continue;
        if (!isfinite(x))
            return fail(inst, "%s: %s %s %s = %g is not finite at t = %.9g", call,
                        MODEL.identifier, v->causality == CAUSALITY_OUTPUT ? "output" : "local",
                        v->name, x, t);
        if (v->type == TYPE_FLOAT64) continue;
        if (!rt_value_fits(v->type, x))
            return fail(inst, "%s: %s %s = %.17g is not a valid %s value at t = %.9g", call,
                        MODEL.identifier, v->name, x, rt_type_name(v->type), t);
        if (v->type == TYPE_FLOAT32) inst->values[i] = (double)(float)x;
    }
    return RT_OK;
}

/* Model Exchange: derivatives, indicators and outputs at the current time. */
static RtStatus me_evaluate(Instance *inst, const char *call)
{
    if (EXT->evaluate(inst->values, inst->state, inst->time, &inst->model_logger) != MODEL_OK)
        return fail(inst, "%s: %s failed to evaluate its equations at t = %.9g (see above)",
                    call, MODEL.identifier, inst->time);
    if (check_outputs(inst, call, inst->time)) return RT_ERROR;
    inst->dirty = 0;
    return RT_OK;
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
    if (rt_has_model_exchange()) {
        inst->time = inst->start_time;
        if (me_evaluate(inst, call)) return RT_ERROR;
    }
    return RT_OK;
}

/* One call of the model's event_update, then re-evaluation; `warned` is set on
   MODEL_WARNING. Returns RT_FATAL or RT_ERROR (logged) on failure. */
static RtStatus me_event_update(Instance *inst, const char *call, ModelEvent *ev, int *warned)
{
    ModelStatus ms = MODEL_OK;
    memset(ev, 0, sizeof *ev);
    ev->next_event_time = INFINITY;
    if (EXT->event_update)
        ms = EXT->event_update(inst->values, inst->state, inst->time, ev, &inst->model_logger);
    switch (ms) {
    case MODEL_OK: break;
    case MODEL_WARNING: *warned = 1; break;
    case MODEL_TERMINATE: ev->terminate = 1; break;
    case MODEL_FATAL:
        fail(inst, "%s: %s reported a fatal error at t = %.9g (see above)", call,
             MODEL.identifier, inst->time);
        return RT_FATAL;
    default:
        return fail(inst, "%s: %s failed to handle the event at t = %.9g (see above)", call,
                    MODEL.identifier, inst->time);
    }
    if (ev->next_event_time != ev->next_event_time) ev->next_event_time = INFINITY;
    if (ev->next_event_time <= inst->time)
        return fail(inst, "%s: %s asked for a time event at t = %.17g, not after the current "
                    "time %.17g", call, MODEL.identifier, ev->next_event_time, inst->time);
    inst->next_event_time = ev->next_event_time;
    if (ev->terminate) inst->terminate_requested = 1;
    return me_evaluate(inst, call);
}

/* The event iteration of an integrated co-simulation: event_update until it
   needs no further update (at most 100 times). */
static RtStatus cs_event_iteration(Instance *inst, const char *call, int *warned)
{
    ModelEvent ev;
    for (int k = 0; k < 100; ++k) {
        RtStatus st = me_event_update(inst, call, &ev, warned);
        if (st) return st;
        if (!ev.needs_update || ev.terminate) return RT_OK;
    }
    return fail(inst, "%s: %s event iteration did not converge in 100 updates at t = %.9g",
                call, MODEL.identifier, inst->time);
}

RtStatus rt_exit_initialization(Instance *inst)
{
    int warned = 0;
    if (require_phase(inst, "exitInitializationMode", IN(PHASE_INIT))) return RT_ERROR;
    if (compute_initial(inst, "exitInitializationMode")) return RT_ERROR;
    inst->time = inst->start_time;
    if (inst->interface == RT_MODEL_EXCHANGE) {
        inst->phase = PHASE_EVENT;
    } else {
        inst->phase = PHASE_STEP;
        if (integrated_cs()) {
            RtStatus st = cs_event_iteration(inst, "exitInitializationMode", &warned);
            if (st) return st;
        }
    }
    rt_log(inst, LOG_OK, "%s initialized at t = %g", MODEL.identifier, inst->start_time);
    return warned ? RT_WARNING : RT_OK;
}

static RtStatus cs_integrate(Instance *inst, double t, double h, int *warned);

RtStatus rt_do_step(Instance *inst, double t, double h)
{
    int warned = 0;
    if (require_phase(inst, "doStep", IN(PHASE_STEP))) return RT_ERROR;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0))
        return fail(inst, "doStep: invalid communication point %g or step size %g (must be > 0)", t, h);
    if (fabs(t - inst->time) > 1e-9 * fmax(1.0, fabs(t)))
        return fail(inst, "doStep: communication point %.17g differs from the FMU time %.17g",
                    t, inst->time);
    if (inst->terminate_requested)
        return fail(inst, "doStep: %s asked to end the simulation at t = %.9g; call terminate",
                    MODEL.identifier, inst->time);
    if (integrated_cs()) {
        RtStatus st = cs_integrate(inst, t, h, &warned);
        if (st) return st;
        return warned ? RT_WARNING : RT_OK;
    }
    switch (MODEL.do_step(inst->values, inst->state, t, h, &inst->model_logger)) {
    case MODEL_OK: break;
    case MODEL_WARNING: warned = 1; break;
    case MODEL_TERMINATE: inst->terminate_requested = 1; break;
    case MODEL_FATAL:
        fail(inst, "doStep: %s reported a fatal error at t = %.9g (see above); "
             "the instance can only be freed", MODEL.identifier, t);
        return RT_FATAL;
    default:
        return fail(inst, "doStep: %s failed at t = %.9g (see above)", MODEL.identifier, t);
    }
    if (check_outputs(inst, "doStep", t + h)) return RT_ERROR;
    inst->time = t + h;
    if (inst->terminate_requested)
        rt_log(inst, LOG_OK, "%s asks to end the simulation at t = %.9g", MODEL.identifier,
               inst->time);
    return warned ? RT_WARNING : RT_OK;
}

RtStatus rt_terminate(Instance *inst)
{
    if (require_phase(inst, "terminate", IN(PHASE_INIT) | RUNNING)) return RT_ERROR;
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
        if (vr[i] < MODEL.n_variables && (MODEL.variables[vr[i]].causality == CAUSALITY_OUTPUT
                                          || MODEL.variables[vr[i]].causality == CAUSALITY_LOCAL))
            return 1;
    return 0;
}

static RtStatus wrong_type(Instance *inst, const char *function, const VariableInfo *v)
{
    return fail(inst, "%s: %s is a %s variable (use the function of its type)",
                function, v->name, rt_type_name(v->type));
}

RtStatus rt_get(Instance *inst, const char *function, unsigned types,
                const unsigned int vr[], size_t n, double out[])
{
    unsigned mask = IN(PHASE_INIT) | RUNNING | IN(PHASE_TERMINATED) | IN(PHASE_ERROR);
    if (require_phase(inst, function, mask)) return RT_ERROR;
    if (inst->phase == PHASE_INIT && wants_output(vr, n)) {
        if (compute_initial(inst, "getting outputs in initialization mode")) return RT_ERROR;
    } else if (inst->dirty && inst->phase != PHASE_ERROR && wants_output(vr, n)) {
        if (me_evaluate(inst, function)) return RT_ERROR;
    }
    for (size_t i = 0; i < n; ++i) {
        if (vr[i] == RT_VR_TIME && (types & RT_TYPE(TYPE_FLOAT64))) {
            out[i] = inst->time;
        } else if (vr[i] < MODEL.n_variables) {
            if (!(types & RT_TYPE(MODEL.variables[vr[i]].type)))
                return wrong_type(inst, function, &MODEL.variables[vr[i]]);
            out[i] = inst->values[vr[i]];
        } else {
            return fail(inst, "get: unknown value reference %u (%s has %u variables)",
                        vr[i], MODEL.identifier, (unsigned)MODEL.n_variables);
        }
    }
    return RT_OK;
}

/* A tunable parameter changed in step or event mode: range and cross-checks at once. */
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
    inst->dirty = inst->interface == RT_MODEL_EXCHANGE;
    return RT_OK;
}

static RtStatus set_one(Instance *inst, const char *function, unsigned types,
                        unsigned int vr, double x)
{
    if (vr >= MODEL.n_variables)
        return fail(inst, "set: unknown or read-only value reference %u", vr);
    const VariableInfo *v = &MODEL.variables[vr];
    if (v->causality == CAUSALITY_OUTPUT)
        return fail(inst, "set: %s is an output and cannot be set", v->name);
    if (v->causality == CAUSALITY_LOCAL)
        return fail(inst, "set: %s is a local variable and cannot be set", v->name);
    if (!(types & RT_TYPE(v->type))) return wrong_type(inst, function, v);
    int running = (RUNNING & IN(inst->phase)) != 0;
    if (v->causality == CAUSALITY_PARAMETER && v->variability == VARIABILITY_FIXED && running)
        return fail(inst, "set: fixed parameter %s can only be set before initialization ends", v->name);
    if (!isfinite(x))
        return fail(inst, "set: %s = %g is not finite (t = %.9g)", v->name, x, inst->time);
    if (v->type != TYPE_FLOAT64 && !rt_value_fits(v->type, x))
        return fail(inst, "set: %s = %.17g cannot be stored as %s (t = %.9g)", v->name, x,
                    rt_type_name(v->type), inst->time);
    if (v->causality == CAUSALITY_INPUT && !(x >= v->min && x <= v->max))
        return fail(inst, "set: input %s = %g is outside its valid range [%g, %g] at t = %.9g",
                    v->name, x, v->min, v->max, inst->time);
    if (v->causality == CAUSALITY_PARAMETER && inst->phase == PHASE_CONTINUOUS)
        return fail(inst, "set: tunable parameter %s can only change in event mode", v->name);
    if (v->causality == CAUSALITY_PARAMETER && running)
        return set_tunable(inst, vr, x);
    inst->values[vr] = x;
    if (running && inst->interface == RT_MODEL_EXCHANGE) inst->dirty = 1;
    return RT_OK;
}

RtStatus rt_set(Instance *inst, const char *function, unsigned types,
                const unsigned int vr[], size_t n, const double in[])
{
    unsigned mask = IN(PHASE_INSTANTIATED) | IN(PHASE_INIT) | RUNNING;
    if (require_phase(inst, function, mask)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i)
        if (set_one(inst, function, types, vr[i], in[i])) return RT_ERROR;
    return RT_OK;
}

RtStatus rt_no_such_type(Instance *inst, const char *function, size_t n)
{
    if (n == 0) return RT_OK;
    return fail(inst, "%s: %s has no variables of this type", function, MODEL.identifier);
}

RtStatus rt_unsupported(Instance *inst, const char *function)
{
    if (!inst) return RT_ERROR;
    return fail(inst, "%s is not supported by %s", function, MODEL.identifier);
}

/* ---- Model Exchange ----------------------------------------------------- */

static RtStatus require_me(Instance *inst, const char *call, unsigned mask)
{
    if (inst->interface != RT_MODEL_EXCHANGE)
        return fail(inst, "%s: this instance of %s is not a Model Exchange instance",
                    call, MODEL.identifier);
    return require_phase(inst, call, mask);
}

static RtStatus require_count(Instance *inst, const char *call, size_t n, size_t expected,
                              const char *what)
{
    if (n == expected) return RT_OK;
    return fail(inst, "%s: %s has %u %s, not %u", call, MODEL.identifier,
                (unsigned)expected, what, (unsigned)n);
}

/* Bring derivatives, indicators and outputs up to date before reading them. */
static RtStatus me_current(Instance *inst, const char *call)
{
    if (inst->phase == PHASE_INIT) return compute_initial(inst, call);
    if (inst->dirty && inst->phase != PHASE_ERROR) return me_evaluate(inst, call);
    return RT_OK;
}

#define ME_READ (IN(PHASE_INIT) | IN(PHASE_EVENT) | IN(PHASE_CONTINUOUS) \
                 | IN(PHASE_TERMINATED) | IN(PHASE_ERROR))

RtStatus rt_enter_event_mode(Instance *inst)
{
    if (require_me(inst, "enterEventMode", IN(PHASE_CONTINUOUS) | IN(PHASE_EVENT))) return RT_ERROR;
    inst->phase = PHASE_EVENT;
    return RT_OK;
}

RtStatus rt_update_discrete_states(Instance *inst, RtEventInfo *info)
{
    ModelEvent ev;
    int warned = 0;
    if (require_me(inst, "updateDiscreteStates/newDiscreteStates", IN(PHASE_EVENT))) return RT_ERROR;
    if (inst->dirty && me_evaluate(inst, "updateDiscreteStates")) return RT_ERROR;
    RtStatus st = me_event_update(inst, "updateDiscreteStates", &ev, &warned);
    if (st) return st;
    info->needs_update = ev.needs_update != 0;
    info->terminate = ev.terminate != 0;
    info->states_changed = ev.states_changed != 0;
    info->next_time_defined = isfinite(ev.next_event_time);
    info->next_time = info->next_time_defined ? ev.next_event_time : 0.0;
    return warned ? RT_WARNING : RT_OK;
}

RtStatus rt_enter_continuous_time_mode(Instance *inst)
{
    if (require_me(inst, "enterContinuousTimeMode", IN(PHASE_EVENT))) return RT_ERROR;
    inst->phase = PHASE_CONTINUOUS;
    return RT_OK;
}

RtStatus rt_completed_integrator_step(Instance *inst, int *enter_event_mode, int *terminate)
{
    if (require_me(inst, "completedIntegratorStep", IN(PHASE_CONTINUOUS))) return RT_ERROR;
    if (enter_event_mode) *enter_event_mode = 0;
    if (terminate) *terminate = inst->terminate_requested;
    return RT_OK;
}

RtStatus rt_set_time(Instance *inst, double t)
{
    if (require_me(inst, "setTime", IN(PHASE_EVENT) | IN(PHASE_CONTINUOUS))) return RT_ERROR;
    if (!isfinite(t)) return fail(inst, "setTime: time %g is not finite", t);
    inst->time = t;
    inst->dirty = 1;
    return RT_OK;
}

RtStatus rt_set_continuous_states(Instance *inst, const double x[], size_t n)
{
    const char *call = "setContinuousStates";
    if (require_me(inst, call, IN(PHASE_EVENT) | IN(PHASE_CONTINUOUS))) return RT_ERROR;
    if (require_count(inst, call, n, rt_n_states(), "continuous states")) return RT_ERROR;
    for (size_t i = 0; i < n; ++i)
        if (!isfinite(x[i]))
            return fail(inst, "%s: state %s = %g is not finite (t = %.9g)", call,
                        MODEL.variables[EXT->state_vrs[i]].name, x[i], inst->time);
    for (size_t i = 0; i < n; ++i) inst->values[EXT->state_vrs[i]] = x[i];
    inst->dirty = 1;
    return RT_OK;
}

static RtStatus me_read(Instance *inst, const char *call, const unsigned *vrs, size_t expected,
                        const char *what, double out[], size_t n)
{
    if (require_me(inst, call, ME_READ)) return RT_ERROR;
    if (require_count(inst, call, n, expected, what)) return RT_ERROR;
    if (me_current(inst, call)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i) out[i] = inst->values[vrs[i]];
    return RT_OK;
}

RtStatus rt_get_continuous_states(Instance *inst, double x[], size_t n)
{
    return me_read(inst, "getContinuousStates", rt_has_model_exchange() ? EXT->state_vrs : NULL,
                   rt_n_states(), "continuous states", x, n);
}

RtStatus rt_get_derivatives(Instance *inst, double dx[], size_t n)
{
    return me_read(inst, "getDerivatives", rt_has_model_exchange() ? EXT->derivative_vrs : NULL,
                   rt_n_states(), "continuous states", dx, n);
}

RtStatus rt_get_event_indicators(Instance *inst, double z[], size_t n)
{
    return me_read(inst, "getEventIndicators", rt_has_model_exchange() ? EXT->indicator_vrs : NULL,
                   rt_n_event_indicators(), "event indicators", z, n);
}

RtStatus rt_get_nominals(Instance *inst, double nominals[], size_t n)
{
    const char *call = "getNominalsOfContinuousStates";
    if (require_me(inst, call, ME_READ | IN(PHASE_INSTANTIATED))) return RT_ERROR;
    if (require_count(inst, call, n, rt_n_states(), "continuous states")) return RT_ERROR;
    for (size_t i = 0; i < n; ++i) nominals[i] = 1.0;
    return RT_OK;
}

/* ---- Co-simulation of a Model Exchange model ------------------------------
 * Classical RK4 sub-steps of at most cs_max_step; a state event (an indicator
 * goes from > 0 to <= 0 or from < 0 to >= 0 within a sub-step) is located by
 * bisection on the sub-step length, redoing one RK4 step from the sub-step
 * start, to 1e-12 s relative; time events end a sub-step exactly. */

static int crossed(const double *z0, const double *z1, size_t n)
{
    for (size_t i = 0; i < n; ++i)
        if ((z0[i] > 0.0 && z1[i] <= 0.0) || (z0[i] < 0.0 && z1[i] >= 0.0)) return 1;
    return 0;
}

static void put_states(Instance *inst, const double *x)
{
    for (size_t i = 0; i < EXT->n_states; ++i) inst->values[EXT->state_vrs[i]] = x[i];
}

static void get_vrs(const Instance *inst, const unsigned *vrs, size_t n, double *out)
{
    for (size_t i = 0; i < n; ++i) out[i] = inst->values[vrs[i]];
}

/* Derivatives at (t, x) into k. */
static RtStatus rhs(Instance *inst, double t, const double *x, double *k)
{
    put_states(inst, x);
    inst->time = t;
    if (me_evaluate(inst, "doStep")) return RT_ERROR;
    get_vrs(inst, EXT->derivative_vrs, EXT->n_states, k);
    return RT_OK;
}

/* One RK4 step of length hs from (t0, x0); leaves the instance evaluated at t0 + hs. */
static RtStatus rk4(Instance *inst, double t0, const double *x0, double hs)
{
    size_t n = EXT->n_states;
    double *k1 = inst->work + n, *k2 = k1 + n, *k3 = k2 + n, *k4 = k3 + n, *x = k4 + n;
    if (rhs(inst, t0, x0, k1)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i) x[i] = x0[i] + 0.5 * hs * k1[i];
    if (rhs(inst, t0 + 0.5 * hs, x, k2)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i) x[i] = x0[i] + 0.5 * hs * k2[i];
    if (rhs(inst, t0 + 0.5 * hs, x, k3)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i) x[i] = x0[i] + hs * k3[i];
    if (rhs(inst, t0 + hs, x, k4)) return RT_ERROR;
    for (size_t i = 0; i < n; ++i) x[i] = x0[i] + hs / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    put_states(inst, x);
    inst->time = t0 + hs;
    return me_evaluate(inst, "doStep");
}

static RtStatus cs_integrate(Instance *inst, double t, double h, int *warned)
{
    size_t n = EXT->n_states, nz = EXT->n_event_indicators;
    double *x0 = inst->work, *z0 = inst->work + 6 * n, *z1 = z0 + nz;
    double t_end = t + h, tol = 1e-12 * fmax(1.0, fabs(t_end));
    double max_step = EXT->cs_max_step > 0.0 ? EXT->cs_max_step : h;
    while (inst->time < t_end - tol && !inst->terminate_requested) {
        double t0 = inst->time, hs = fmin(max_step, t_end - t0);
        int time_event = 0, event = 0;
        if (inst->next_event_time <= t0 + hs + tol) {
            hs = fmax(0.0, inst->next_event_time - t0);
            time_event = 1;
        }
        get_vrs(inst, EXT->state_vrs, n, x0);
        get_vrs(inst, EXT->indicator_vrs, nz, z0);
        if (hs > 0.0 && rk4(inst, t0, x0, hs)) return RT_ERROR;
        get_vrs(inst, EXT->indicator_vrs, nz, z1);
        if (crossed(z0, z1, nz)) {
            double lo = 0.0, hi = hs;
            for (int k = 0; k < 200 && hi - lo > 1e-12 * fmax(1.0, fabs(t0)); ++k) {
                double mid = 0.5 * (lo + hi);
                if (rk4(inst, t0, x0, mid)) return RT_ERROR;
                get_vrs(inst, EXT->indicator_vrs, nz, z1);
                if (crossed(z0, z1, nz)) hi = mid;
                else lo = mid;
            }
            if (rk4(inst, t0, x0, hi)) return RT_ERROR;
            if (hi < hs) time_event = 0;
            event = 1;
        } else if (time_event) {
            inst->time = inst->next_event_time;
            event = 1;
        }
        if (hs == t_end - t0 && !event) inst->time = t_end;
        if (event) {
            if (time_event) inst->time = inst->next_event_time;
            if (inst->dirty && me_evaluate(inst, "doStep")) return RT_ERROR;
            RtStatus st = cs_event_iteration(inst, "doStep", warned);
            if (st) return st;
        }
    }
    if (!inst->terminate_requested) inst->time = t_end;
    return RT_OK;
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

RtStatus rt_get_state(Instance *inst, RtState **state)
{
    if (!state) return fail(inst, "getFMUState: null pointer");
    if (!*state) *state = state_alloc();
    if (!*state) return fail(inst, "getFMUState: out of memory");
    RtState *s = *state;
    s->phase = inst->phase;
    s->start_time = inst->start_time;
    s->time = inst->time;
    s->flags = inst->terminate_requested | inst->dirty << 1;
    s->next_event_time = inst->next_event_time;
    memcpy(s->values, inst->values, MODEL.n_variables * sizeof(double));
    memcpy(s->state, inst->state, MODEL.state_size);
    return RT_OK;
}

RtStatus rt_set_state(Instance *inst, const RtState *s)
{
    if (!s) return fail(inst, "setFMUState: null state");
    inst->phase = s->phase;
    inst->start_time = s->start_time;
    inst->time = s->time;
    inst->terminate_requested = s->flags & 1;
    inst->dirty = (s->flags >> 1) & 1;
    inst->next_event_time = s->next_event_time;
    memcpy(inst->values, s->values, MODEL.n_variables * sizeof(double));
    memcpy(inst->state, s->state, MODEL.state_size);
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

/* Layout: guid '\0' | int32 phase, flags | double start_time, time, next_event_time
   | values | state. */
size_t rt_serialized_size(const Instance *inst)
{
    (void)inst;
    return strlen(MODEL.guid) + 1 + 2 * sizeof(int32_t) + 3 * sizeof(double)
           + MODEL.n_variables * sizeof(double) + MODEL.state_size;
}

RtStatus rt_serialize(Instance *inst, const RtState *s, unsigned char *buf, size_t size)
{
    size_t need = rt_serialized_size(inst), g = strlen(MODEL.guid) + 1;
    if (!s || !buf || size < need)
        return fail(inst, "serializeFMUState: buffer of %u bytes, %u needed",
                    (unsigned)size, (unsigned)need);
    int32_t head[2] = {(int32_t)s->phase, (int32_t)s->flags};
    double times[3] = {s->start_time, s->time, s->next_event_time};
    memcpy(buf, MODEL.guid, g); buf += g;
    memcpy(buf, head, sizeof head); buf += sizeof head;
    memcpy(buf, times, sizeof times); buf += sizeof times;
    memcpy(buf, s->values, MODEL.n_variables * sizeof(double));
    buf += MODEL.n_variables * sizeof(double);
    memcpy(buf, s->state, MODEL.state_size);
    return RT_OK;
}

RtStatus rt_deserialize(Instance *inst, const unsigned char *buf, size_t size, RtState **state)
{
    size_t g = strlen(MODEL.guid) + 1;
    int32_t head[2];
    double times[3];
    if (!buf || size != rt_serialized_size(inst) || memcmp(buf, MODEL.guid, g) != 0)
        return fail(inst, "deserializeFMUState: %u bytes are not a serialized %s state",
                    (unsigned)size, MODEL.identifier);
    memcpy(head, buf + g, sizeof head);
    if (head[0] < PHASE_INSTANTIATED || head[0] >= PHASE_COUNT)
        return fail(inst, "deserializeFMUState: corrupt phase %d", (int)head[0]);
    if (!state) return fail(inst, "deserializeFMUState: null pointer");
    if (!*state) *state = state_alloc();
    if (!*state) return fail(inst, "deserializeFMUState: out of memory");
    RtState *s = *state;
    buf += g + sizeof head;
    memcpy(times, buf, sizeof times); buf += sizeof times;
    s->phase = (Phase)head[0];
    s->flags = head[1];
    s->start_time = times[0];
    s->time = times[1];
    s->next_event_time = times[2];
    memcpy(s->values, buf, MODEL.n_variables * sizeof(double));
    buf += MODEL.n_variables * sizeof(double);
    memcpy(s->state, buf, MODEL.state_size);
    return RT_OK;
}
