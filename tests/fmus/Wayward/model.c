/*
 * Wayward: a hand-written FMI 2.0 co-simulation FMU (not the framework, whose
 * calls outside doStep cannot fail on purpose) that misbehaves outside doStep,
 * for tests/execution/test_fmu_faults.py. Built by the tests with gcc
 * (the `wayward` fixture there); modelDescription.xml is beside this file.
 *
 * Variables: u (input, vr 0), y = t (output, vr 1), fault (parameter, vr 2).
 * fault:
 *   0 none
 *   1 fmi2Terminate writes through a null pointer (SIGSEGV)
 *   2 fmi2Terminate never returns
 *   3 fmi2Terminate returns Error (after logging it)
 *   4 fmi2FreeInstance writes through a null pointer (SIGSEGV)
 *   5 fmi2SetupExperiment never returns
 *   6 fmi2DoStep returns Pending from the step ending at t >= 0.2 on (tick 20
 *     with steps of 0.01 s), which no caller asked for (asynchronous steps)
 * The instance name (the component's name) selects faults of fmi2Instantiate,
 * which come before any parameter is set: "inst_null" returns NULL,
 * "inst_hang" never returns.
 */
#define _POSIX_C_SOURCE 200809L

#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "fmi2Functions.h"

typedef struct {
    double u, y, fault, t;
    const fmi2CallbackFunctions *cb;
    fmi2String name;
} Wayward;

enum { NONE, TERM_SEGV, TERM_HANG, TERM_ERROR, FREE_SEGV, SETUP_HANG, STEP_PENDING };

static int fault(fmi2Component c) { return (int)((Wayward *)c)->fault; }
static void hang(void) { for (;;) pause(); }
static void segfault(void) { volatile int *volatile p = NULL; *p = 1; }

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[])
{ (void)c; (void)on; (void)n; (void)cat; return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean log)
{
    (void)type; (void)guid; (void)resources; (void)visible; (void)log;
    if (strcmp(name, "inst_null") == 0) return NULL;
    if (strcmp(name, "inst_hang") == 0) hang();
    Wayward *w = calloc(1, sizeof *w);
    w->cb = cb;
    w->name = name;
    return w;
}

void fmi2FreeInstance(fmi2Component c)
{
    if (fault(c) == FREE_SEGV) segfault();
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean sd, fmi2Real stop)
{
    (void)td; (void)tol; (void)sd; (void)stop;
    if (fault(c) == SETUP_HANG) hang();
    ((Wayward *)c)->t = ((Wayward *)c)->y = t0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2Terminate(fmi2Component c)
{
    Wayward *w = c;
    switch (fault(c)) {
    case TERM_SEGV: segfault(); break;
    case TERM_HANG: hang(); break;
    case TERM_ERROR:
        w->cb->logger(w->cb->componentEnvironment, w->name, fmi2Error, "logStatusError",
                      "Wayward: injected error in fmi2Terminate at t = %g", w->t);
        return fmi2Error;
    default: break;
    }
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[])
{
    Wayward *w = c;
    for (size_t k = 0; k < n; k++)
        v[k] = vr[k] == 0 ? w->u : vr[k] == 1 ? w->y : w->fault;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[])
{
    Wayward *w = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 0) w->u = v[k];
        else if (vr[k] == 2) w->fault = v[k];
        else return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
{ (void)c; (void)vr; (void)n; (void)v; return fmi2Error; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
{ (void)c; (void)vr; (void)n; (void)v; return fmi2Error; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{ (void)c; (void)vr; (void)n; (void)v; return fmi2Error; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{ (void)c; (void)vr; (void)n; (void)v; return fmi2Error; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{ (void)c; (void)vr; (void)n; (void)v; return fmi2Error; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{ (void)c; (void)vr; (void)n; (void)v; return fmi2Error; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{ (void)c; (void)s; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{ (void)c; (void)s; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
{ (void)c; (void)b; (void)n; (void)s; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb,
                                        const fmi2Real dv[], fmi2Real d[])
{ (void)c; (void)a; (void)na; (void)b; (void)nb; (void)dv; (void)d; return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[])
{ (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[])
{ (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean nsp)
{
    Wayward *w = c;
    (void)nsp;
    if (fault(c) == STEP_PENDING && t + h >= 0.2 - 1e-9) return fmi2Pending;
    w->t = w->y = t + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{ (void)c; (void)s; *v = fmi2OK; return fmi2OK; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{ (void)s; *v = ((Wayward *)c)->t; return fmi2OK; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{ (void)c; (void)s; *v = fmi2False; return fmi2OK; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
