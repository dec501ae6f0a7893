/*
 * Faulty: a test-only FMU whose parameter fault_mode selects a failure that
 * fires inside doStep at fault_time, so the platform can be tested against
 * foreign FMUs that crash, hang, terminate, log or fail. Modes (fault_mode):
 *   0 none              the FMU works normally
 *   1 segfault          writes through a null pointer (SIGSEGV)
 *   2 abort             calls abort() (SIGABRT)
 *   3 exit              calls exit(3): the importer process exits with code 3
 *   4 hang (busy)       spins in an infinite loop, doStep never returns
 *   5 fatal             logs an error, doStep returns Fatal
 *   6 error             logs "Faulty: injected error ..." (logStatusError),
 *                       doStep returns Error
 *   7 terminate         completes the step, then asks to end the simulation:
 *                       FMI2 Discard with fmi2Terminated = true and
 *                       fmi2LastSuccessfulTime = t + h; FMI3 OK with
 *                       terminateSimulation = true
 *   8 hang (sleeping)   blocks in nanosleep forever (no CPU), never returns
 *   9 warnings          from fault_time on, every step logs a warning
 *                       (logStatusWarning) and returns Warning; values stay right
 *  10 NaN output        y becomes NaN: the framework's output check fails the
 *                       step with Error
 * The fault fires in the first doStep whose end t + h reaches fault_time
 * (within 1e-9 relative); the outputs of that step are not updated, except in
 * modes 7 and 9 (the step completes).
 *
 * Outputs of several types for recording tests: y = t (Float64), y_f32
 * (Float32), u_echo = u, ticks = n * tick_increment after n steps (Int32),
 * ticks_u8 = n mod 256 (UInt8), ticks_i16 = -(n mod 30000) (Int16),
 * flag = (n odd) xor invert_flag (Boolean), k_twice = 2 k_in (Int32),
 * b_not = !b_in (Boolean).
 *
 * variant.h (per model folder) gives the identifier, token and flags, so
 * tests/fmus/FaultyOnce builds the same code with
 * canBeInstantiatedOnlyOncePerProcess="true", and tests/fmus/FaultyME as a
 * Model Exchange FMU (FAULTY_MODEL_EXCHANGE) whose fault fires in the event
 * iteration of the time event at fault_time.
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdlib.h>
#include <time.h>

#include "model.h"
#include "variable_table.h"
#include "variant.h"

#ifndef FAULTY_MODEL_EXCHANGE
#define FAULTY_MODEL_EXCHANGE 0  /* variant.h of FaultyME sets 1 */
#endif

static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#define TVAR MODEL_TYPED_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
#undef TVAR
};

enum {
    FAULT_NONE, FAULT_SEGFAULT, FAULT_ABORT, FAULT_EXIT, FAULT_HANG_BUSY, FAULT_FATAL,
    FAULT_ERROR, FAULT_TERMINATE, FAULT_HANG_SLEEP, FAULT_WARNINGS, FAULT_NAN, FAULT_COUNT
};

static const char *const FAULT_NAMES[FAULT_COUNT] = {
    "none", "segfault", "abort", "exit(3)", "hang (busy loop)", "fatal status",
    "error with log message", "termination request", "hang (sleeping)", "warnings", "NaN output"
};

typedef struct {
    double steps;   /* completed steps (exact in a double up to 2^53) */
    int fired;      /* the fault has fired */
} FaultyState;

static ModelStatus validate(const double *values, const ModelLogger *log)
{
    double mode = values[VR_fault_mode];
    if (mode != floor(mode)) {
        model_logf(log, LOG_ERROR, "Faulty: fault_mode must be an integer 0..%d, got %g",
                   FAULT_COUNT - 1, mode);
        return MODEL_ERROR;
    }
    return MODEL_OK;
}

/* Outputs after `steps` completed steps, at time t. */
static void set_outputs(double *values, double steps, double t)
{
    values[VR_y] = t;
    values[VR_y_f32] = (double)(float)t;
    values[VR_u_echo] = values[VR_u];
    values[VR_ticks] = steps * values[VR_tick_increment];
    values[VR_ticks_u8] = fmod(steps, 256.0);
    values[VR_ticks_i16] = -fmod(steps, 30000.0);
    values[VR_flag] = (fmod(steps, 2.0) == 1.0) != (values[VR_invert_flag] != 0.0);
    values[VR_k_twice] = 2.0 * values[VR_k_in];
    values[VR_b_not] = values[VR_b_in] == 0.0;
}

static ModelStatus initialize(double *values, void *state, double t0, const ModelLogger *log)
{
    (void)state; (void)log;
    set_outputs(values, 0.0, t0);
    return MODEL_OK;
}

static void crash_segfault(void)
{
    volatile int *volatile p = NULL;  /* both volatile: the store cannot be optimized away */
    *p = 42;
}

static void hang_busy(void)
{
    volatile unsigned long spin = 0;
    for (;;) ++spin;
}

static void hang_sleeping(void)
{
    for (;;) {
        struct timespec ts = {3600, 0};
        nanosleep(&ts, NULL);
    }
}

/* Fires the fault; returns the status of the step for the modes that return. */
static ModelStatus fire(int mode, double t, double h, const ModelLogger *log)
{
    model_logf(log, LOG_OK, "Faulty: fault_mode %d (%s) fires in the step from t = %g to %g",
               mode, FAULT_NAMES[mode], t, t + h);
    switch (mode) {
    case FAULT_SEGFAULT: crash_segfault(); break;
    case FAULT_ABORT: abort();
    case FAULT_EXIT: exit(3);
    case FAULT_HANG_BUSY: hang_busy(); break;
    case FAULT_HANG_SLEEP: hang_sleeping(); break;
    case FAULT_FATAL:
        model_logf(log, LOG_ERROR, "Faulty: injected fatal error in the step from t = %g to %g "
                   "(fault_mode 5)", t, t + h);
        return MODEL_FATAL;
    case FAULT_ERROR:
        model_logf(log, LOG_ERROR, "Faulty: injected error in the step from t = %g to %g "
                   "(fault_mode 6)", t, t + h);
        return MODEL_ERROR;
    default: break;
    }
    return MODEL_OK;
}

static ModelStatus do_step(double *values, void *state, double t, double h, const ModelLogger *log)
{
    FaultyState *st = state;
    int mode = (int)values[VR_fault_mode];
    double fault_time = values[VR_fault_time];
    ModelStatus status = MODEL_OK;
    if (mode != FAULT_NONE && !st->fired
        && t + h >= fault_time - 1e-9 * fmax(1.0, fabs(fault_time))) {
        st->fired = 1;
        status = fire(mode, t, h, log);
        if (status != MODEL_OK) return status;
    }
    st->steps += 1.0;
    set_outputs(values, st->steps, t + h);
    if (st->fired && mode == FAULT_TERMINATE) return MODEL_TERMINATE;
    if (st->fired && mode == FAULT_WARNINGS) {
        model_logf(log, LOG_WARNING, "Faulty: injected warning in the step from t = %g to %g "
                   "(fault_mode 9)", t, t + h);
        return MODEL_WARNING;
    }
    if (st->fired && mode == FAULT_NAN) values[VR_y] = NAN;
    return MODEL_OK;
}

const ModelDefinition MODEL = {
    FAULTY_IDENTIFIER,
    FAULTY_GUID,
    FAULTY_DESCRIPTION,
    VARIABLES,
    sizeof VARIABLES / sizeof VARIABLES[0],
    sizeof(FaultyState),
    0.1,
    validate,
    initialize,
    do_step,
};

#if FAULTY_MODEL_EXCHANGE
/* Model Exchange (tests/fmus/FaultyME): no continuous state, y = t; the fault
   fires in the event iteration at the time event fault_time. */
static ModelStatus evaluate(double *values, void *state, double t, const ModelLogger *log)
{
    (void)state; (void)log;
    values[VR_y] = t;
    values[VR_y_f32] = (double)(float)t;
    values[VR_u_echo] = values[VR_u];
    return MODEL_OK;
}

static ModelStatus event_update(double *values, void *state, double t, ModelEvent *event,
                                const ModelLogger *log)
{
    FaultyState *st = state;
    int mode = (int)values[VR_fault_mode];
    double fault_time = values[VR_fault_time];
    if (mode == FAULT_NONE || st->fired) return MODEL_OK;
    if (t < fault_time - 1e-9 * fmax(1.0, fabs(fault_time))) {
        event->next_event_time = fault_time;
        return MODEL_OK;
    }
    st->fired = 1;
    ModelStatus status = fire(mode, t, 0.0, log);
    if (status != MODEL_OK) return status;
    return mode == FAULT_TERMINATE ? MODEL_TERMINATE : MODEL_OK;
}

const ModelExtension MODEL_EXTENSION = {FAULTY_FLAGS, 0, NULL, NULL, 0, NULL, evaluate,
                                        event_update, 0.0};
#else
const ModelExtension MODEL_EXTENSION = {FAULTY_FLAGS, 0, NULL, NULL, 0, NULL, NULL, NULL, 0.0};
#endif
