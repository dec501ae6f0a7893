/*
 * xmlgen.c - build-time generator of modelDescription.xml (FMI 2.0 or 3.0).
 *
 * Compiled and linked with a model's code, so the variable table is read by
 * the compiler only: `xmlgen 2|3 [source files...]` prints the description of
 * MODEL on stdout; the source file names go into FMI2 <SourceFiles>.
 * Exits non-zero with a message on stderr for a table it cannot express
 * (unknown unit, a type without FMI 2.0 equivalent, an integer or Boolean
 * variable declared continuous, inconsistent Model Exchange lists, ...).
 * With MODEL_EXTENSION it adds <ModelExchange> (Model Exchange models), drops
 * <CoSimulation> (MODEL_FLAG_NO_COSIMULATION), sets
 * canBeInstantiatedOnlyOncePerProcess, and lists derivatives and event
 * indicators in ModelStructure.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"
#include "runtime.h"

typedef struct {
    const char *name;
    int kg, m, s, rad;
} UnitDef;

/* SI units the models may use, as exponents of the FMI base units. */
static const UnitDef UNITS[] = {
    {"1", 0, 0, 0, 0},          {"m", 0, 1, 0, 0},          {"kg", 1, 0, 0, 0},
    {"s", 0, 0, 1, 0},          {"rad", 0, 0, 0, 1},        {"m/s", 0, 1, -1, 0},
    {"m/s2", 0, 1, -2, 0},      {"rad/s", 0, 0, -1, 1},     {"rad/s2", 0, 0, -2, 1},
    {"N", 1, 1, -2, 0},         {"N.m", 1, 2, -2, 0},       {"kg.m2", 1, 2, 0, 0},
    {"N/rad", 1, 1, -2, -1},    {"N.m/rad", 1, 2, -2, -1},  {"N.m.s/rad", 1, 2, -1, -1},
    {"N/m", 1, 0, -2, 0},       {"N.s/m", 1, 0, -1, 0},     {"kg/m", 1, -1, 0, 0},
    {"1/m", 0, -1, 0, 0},       {"m2", 0, 2, 0, 0},         {"kg/m3", 1, -3, 0, 0},
    {"1/rad", 0, 0, 0, -1},     {"1/s", 0, 0, -1, 0},       {"N/m2", 1, -1, -2, 0},
};
#define N_UNITS (sizeof UNITS / sizeof UNITS[0])

static const UnitDef *find_unit(const char *name)
{
    for (size_t i = 0; i < N_UNITS; ++i)
        if (strcmp(UNITS[i].name, name) == 0) return &UNITS[i];
    return NULL;
}

static void print_escaped(const char *s)
{
    for (; *s; ++s) {
        switch (*s) {
        case '&': fputs("&amp;", stdout); break;
        case '<': fputs("&lt;", stdout); break;
        case '>': fputs("&gt;", stdout); break;
        case '"': fputs("&quot;", stdout); break;
        default: putchar(*s);
        }
    }
}

/* Shortest decimal that reads back to the same double. */
static void print_double(const char *attr, double x)
{
    char buf[40];
    if (x == floor(x) && fabs(x) < 1e15) {
        printf(" %s=\"%.0f\"", attr, x);
        return;
    }
    for (int prec = 1; prec <= 17; ++prec) {
        snprintf(buf, sizeof buf, "%.*g", prec, x);
        if (strtod(buf, NULL) == x) break;
    }
    printf(" %s=\"%s\"", attr, buf);
}

static int is_float(VarType t)
{
    return t == TYPE_FLOAT64 || t == TYPE_FLOAT32;
}

#define HAS_EXT (&MODEL_EXTENSION != NULL)
#define EXT (&MODEL_EXTENSION)

static int has_me(void)
{
    return HAS_EXT && EXT->evaluate != NULL;
}

static int has_cs(void)
{
    if (HAS_EXT && (EXT->flags & MODEL_FLAG_NO_COSIMULATION)) return 0;
    return MODEL.do_step != NULL || has_me();
}

static const char *once_attribute(void)
{
    return HAS_EXT && (EXT->flags & MODEL_FLAG_ONE_INSTANCE_PER_PROCESS)
           ? " canBeInstantiatedOnlyOncePerProcess=\"true\"" : "";
}

/* Index in `list` of value reference vr (as state, derivative, ...), or -1. */
static long find_vr(const unsigned *list, size_t n, size_t vr)
{
    for (size_t i = 0; i < n; ++i)
        if (list[i] == vr) return (long)i;
    return -1;
}

static long state_of_derivative(size_t vr)
{
    if (!has_me()) return -1;
    long k = find_vr(EXT->derivative_vrs, EXT->n_states, vr);
    return k < 0 ? -1 : (long)EXT->state_vrs[k];
}

static void print_unit_definitions(void)
{
    const char *used[64];
    size_t n = 0;
    puts("  <UnitDefinitions>");
    for (size_t i = 0; i <= MODEL.n_variables; ++i) {
        const char *u = i < MODEL.n_variables ? MODEL.variables[i].unit : "s";
        if (i < MODEL.n_variables && !is_float(MODEL.variables[i].type)) continue;
        size_t k = 0;
        while (k < n && strcmp(used[k], u) != 0) ++k;
        if (k < n || n == 64) continue;
        used[n++] = u;
        const UnitDef *d = find_unit(u);
        printf("    <Unit name=\"%s\"><BaseUnit", u);
        if (d->kg) printf(" kg=\"%d\"", d->kg);
        if (d->m) printf(" m=\"%d\"", d->m);
        if (d->s) printf(" s=\"%d\"", d->s);
        if (d->rad) printf(" rad=\"%d\"", d->rad);
        puts("/></Unit>");
    }
    puts("  </UnitDefinitions>");
}

static void print_log_categories(void)
{
    puts("  <LogCategories>\n"
         "    <Category name=\"logStatusError\" description=\"errors\"/>\n"
         "    <Category name=\"logStatusWarning\" description=\"warnings\"/>\n"
         "    <Category name=\"logInfo\" description=\"debug information\"/>\n"
         "  </LogCategories>");
}

static const char *causality_name(Causality c)
{
    switch (c) {
    case CAUSALITY_PARAMETER: return "parameter";
    case CAUSALITY_INPUT: return "input";
    case CAUSALITY_LOCAL: return "local";
    default: return "output";
    }
}

static const char *variability_name(const VariableInfo *v)
{
    if (v->causality != CAUSALITY_PARAMETER)
        return v->variability == VARIABILITY_DISCRETE ? "discrete" : "continuous";
    return v->variability == VARIABILITY_TUNABLE ? "tunable" : "fixed";
}

static const char *initial_attribute(const VariableInfo *v)
{
    if (v->causality == CAUSALITY_PARAMETER) return " initial=\"exact\"";
    return v->causality == CAUSALITY_INPUT ? "" : " initial=\"calculated\"";
}

/* Element name of a variable's type. */
static const char *type_element(const VariableInfo *v, int version)
{
    if (version == 3) return rt_type_name(v->type);
    if (is_float(v->type)) return "Real";
    return v->type == TYPE_BOOLEAN ? "Boolean" : "Integer";
}

/* One <element attribute="N"/> line per output, N = its value reference + base
   (FMI 2 lists outputs by 1-based variable index, FMI 3 by value reference). */
static void print_outputs(const char *indent, const char *element, const char *attribute,
                          unsigned base)
{
    for (size_t i = 0; i < MODEL.n_variables; ++i)
        if (MODEL.variables[i].causality == CAUSALITY_OUTPUT)
            printf("%s<%s %s=\"%u\"/>\n", indent, element, attribute, (unsigned)i + base);
}

/* Unknowns of InitialUnknowns: outputs, continuous states and derivatives
   (all initial="calculated"), by value reference + base, in table order. */
static int is_initial_unknown(size_t i)
{
    if (MODEL.variables[i].causality == CAUSALITY_OUTPUT) return 1;
    return has_me() && (find_vr(EXT->state_vrs, EXT->n_states, i) >= 0
                        || find_vr(EXT->derivative_vrs, EXT->n_states, i) >= 0);
}

static void print_initial_unknowns(const char *indent, const char *element, const char *attribute,
                                   unsigned base)
{
    for (size_t i = 0; i < MODEL.n_variables; ++i)
        if (is_initial_unknown(i))
            printf("%s<%s %s=\"%u\"/>\n", indent, element, attribute, (unsigned)i + base);
}

/* Value reference list (derivatives, indicators) as <element attribute="vr + base"/>. */
static void print_vr_list(const char *indent, const char *element, const char *attribute,
                          const unsigned *vrs, size_t n, unsigned base)
{
    for (size_t i = 0; i < n; ++i)
        printf("%s<%s %s=\"%u\"/>\n", indent, element, attribute, vrs[i] + base);
}

/* Type attributes: unit (floats), start (not outputs/locals), min, max,
   derivative (FMI2: 1-based index of the state, FMI3: its value reference). */
static void print_value_attributes(const VariableInfo *v, size_t vr, int version)
{
    int has_start = v->causality == CAUSALITY_PARAMETER || v->causality == CAUSALITY_INPUT;
    if (is_float(v->type)) printf(" unit=\"%s\"", v->unit);
    if (has_start && v->type == TYPE_BOOLEAN) printf(" start=\"%s\"", v->start != 0.0 ? "true" : "false");
    else if (has_start) print_double("start", v->start);
    if (v->type != TYPE_BOOLEAN) {
        if (isfinite(v->min)) print_double("min", v->min);
        if (isfinite(v->max)) print_double("max", v->max);
    }
    long state = state_of_derivative(vr);
    if (state >= 0) printf(" derivative=\"%ld\"", state + (version == 2 ? 1 : 0));
}

static void print_header(int version)
{
    puts("<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    printf("<fmiModelDescription fmiVersion=\"%s\" modelName=\"%s\" %s=\"%s\"\n  description=\"",
           version == 2 ? "2.0" : "3.0", MODEL.identifier,
           version == 2 ? "guid" : "instantiationToken", MODEL.guid);
    print_escaped(MODEL.description);
    printf("\"\n  generationTool=\"cosim fmu_build (xmlgen.c)\" variableNamingConvention=\"flat\"");
    if (version == 2)
        printf(" numberOfEventIndicators=\"%u\"",
               has_me() ? (unsigned)EXT->n_event_indicators : 0u);
    puts(">");
}

static void print_source_files(int argc, char **argv)
{
    puts("    <SourceFiles>");
    for (int i = 0; i < argc; ++i) printf("      <File name=\"%s\"/>\n", argv[i]);
    puts("    </SourceFiles>");
}

static void print_fmi2(int argc, char **argv)
{
    print_header(2);
    if (has_me()) {
        printf("  <ModelExchange modelIdentifier=\"%s\" completedIntegratorStepNotNeeded=\"true\"\n"
               "    canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\""
               " canNotUseMemoryManagementFunctions=\"true\"%s>\n", MODEL.identifier,
               once_attribute());
        print_source_files(argc, argv);
        puts("  </ModelExchange>");
    }
    if (has_cs()) {
        printf("  <CoSimulation modelIdentifier=\"%s\" canHandleVariableCommunicationStepSize=\"true\"\n"
               "    canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\""
               " canNotUseMemoryManagementFunctions=\"true\"%s>\n", MODEL.identifier,
               once_attribute());
        print_source_files(argc, argv);
        puts("  </CoSimulation>");
    }
    print_unit_definitions();
    print_log_categories();
    printf("  <DefaultExperiment startTime=\"0\"");
    print_double("stepSize", MODEL.default_step);
    puts("/>\n  <ModelVariables>");
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        printf("    <!-- index %u -->\n    <ScalarVariable name=\"%s\" valueReference=\"%u\" description=\"",
               (unsigned)(i + 1), v->name, (unsigned)i);
        print_escaped(v->description);
        printf("\"\n      causality=\"%s\" variability=\"%s\"%s>\n      <%s",
               causality_name(v->causality), variability_name(v), initial_attribute(v),
               type_element(v, 2));
        print_value_attributes(v, i, 2);
        puts("/>\n    </ScalarVariable>");
    }
    puts("  </ModelVariables>\n  <ModelStructure>\n    <Outputs>");
    print_outputs("      ", "Unknown", "index", 1);
    puts("    </Outputs>");
    if (has_me() && EXT->n_states > 0) {
        puts("    <Derivatives>");
        print_vr_list("      ", "Unknown", "index", EXT->derivative_vrs, EXT->n_states, 1);
        puts("    </Derivatives>");
    }
    puts("    <InitialUnknowns>");
    print_initial_unknowns("      ", "Unknown", "index", 1);
    puts("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>");
}

static void print_fmi3(void)
{
    print_header(3);
    if (has_me())
        printf("  <ModelExchange modelIdentifier=\"%s\" needsCompletedIntegratorStep=\"false\"\n"
               "    canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\"%s/>\n",
               MODEL.identifier, once_attribute());
    if (has_cs())
        printf("  <CoSimulation modelIdentifier=\"%s\" canHandleVariableCommunicationStepSize=\"true\"\n"
               "    canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" hasEventMode=\"false\""
               " providesIntermediateUpdate=\"false\"%s/>\n", MODEL.identifier, once_attribute());
    print_unit_definitions();
    print_log_categories();
    printf("  <DefaultExperiment startTime=\"0\"");
    print_double("stepSize", MODEL.default_step);
    printf("/>\n  <ModelVariables>\n    <Float64 name=\"time\" valueReference=\"%u\""
           " causality=\"independent\" variability=\"continuous\" unit=\"s\""
           " description=\"simulation time\"/>\n", RT_VR_TIME);
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        printf("    <%s name=\"%s\" valueReference=\"%u\" description=\"", type_element(v, 3),
               v->name, (unsigned)i);
        print_escaped(v->description);
        printf("\"\n      causality=\"%s\" variability=\"%s\"%s", causality_name(v->causality),
               variability_name(v), initial_attribute(v));
        print_value_attributes(v, i, 3);
        puts("/>");
    }
    puts("  </ModelVariables>\n  <ModelStructure>");
    print_outputs("    ", "Output", "valueReference", 0);
    if (has_me())
        print_vr_list("    ", "ContinuousStateDerivative", "valueReference", EXT->derivative_vrs,
                      EXT->n_states, 0);
    print_initial_unknowns("    ", "InitialUnknown", "valueReference", 0);
    if (has_me())
        print_vr_list("    ", "EventIndicator", "valueReference", EXT->indicator_vrs,
                      EXT->n_event_indicators, 0);
    puts("  </ModelStructure>\n</fmiModelDescription>");
}

/* A Model Exchange list entry must be a Float64 continuous output or local. */
static int check_me_vr(const char *what, size_t k, unsigned vr)
{
    if (vr >= MODEL.n_variables) {
        fprintf(stderr, "%s %s %u: value reference %u is not in the table\n",
                MODEL.identifier, what, (unsigned)k, vr);
        return 1;
    }
    const VariableInfo *v = &MODEL.variables[vr];
    if (v->type != TYPE_FLOAT64 || v->variability != VARIABILITY_CONTINUOUS
        || (v->causality != CAUSALITY_OUTPUT && v->causality != CAUSALITY_LOCAL)) {
        fprintf(stderr, "%s %s %s: must be a Float64 CONTINUOUS OUTPUT or LOCAL variable\n",
                MODEL.identifier, what, v->name);
        return 1;
    }
    return 0;
}

static int check_model_exchange(void)
{
    int bad = 0;
    if (!HAS_EXT) return 0;
    if (!has_me() && (EXT->n_states || EXT->n_event_indicators)) {
        fprintf(stderr, "%s: MODEL_EXTENSION lists states or event indicators but has no "
                "evaluate function\n", MODEL.identifier);
        return 1;
    }
    if (!has_me()) return 0;
    if (EXT->n_states && (!EXT->state_vrs || !EXT->derivative_vrs)) {
        fprintf(stderr, "%s: MODEL_EXTENSION has n_states but no state/derivative lists\n",
                MODEL.identifier);
        return 1;
    }
    if (EXT->n_event_indicators && !EXT->indicator_vrs) {
        fprintf(stderr, "%s: MODEL_EXTENSION has n_event_indicators but no list\n",
                MODEL.identifier);
        return 1;
    }
    for (size_t k = 0; k < EXT->n_states; ++k) {
        bad += check_me_vr("continuous state", k, EXT->state_vrs[k]);
        bad += check_me_vr("derivative", k, EXT->derivative_vrs[k]);
    }
    for (size_t k = 0; k < EXT->n_event_indicators; ++k)
        bad += check_me_vr("event indicator", k, EXT->indicator_vrs[k]);
    return bad;
}

/* Reject what the XML could not express faithfully. */
static int check_table(int version)
{
    int bad = check_model_exchange();
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        if (v->type >= TYPE_COUNT) {
            fprintf(stderr, "%s variable %s: invalid type\n", MODEL.identifier, v->name);
            ++bad;
            continue;
        }
        if (!is_float(v->type)) {
            if (v->unit[0] != '\0') {
                fprintf(stderr, "%s variable %s: a %s variable has no unit (write \"\")\n",
                        MODEL.identifier, v->name, rt_type_name(v->type));
                ++bad;
            }
            if (v->variability == VARIABILITY_CONTINUOUS) {
                fprintf(stderr, "%s variable %s: a %s variable cannot be CONTINUOUS (use DISCRETE)\n",
                        MODEL.identifier, v->name, rt_type_name(v->type));
                ++bad;
            }
            if (version == 2 && (v->type == TYPE_UINT32 || v->type == TYPE_INT64
                                 || v->type == TYPE_UINT64)) {
                fprintf(stderr, "%s variable %s: type %s has no FMI 2.0 equivalent (FMI 3.0 only)\n",
                        MODEL.identifier, v->name, rt_type_name(v->type));
                ++bad;
            }
        } else if (!find_unit(v->unit)) {
            fprintf(stderr, "%s variable %s: unknown unit '%s' (add it to UNITS in xmlgen.c)\n",
                    MODEL.identifier, v->name, v->unit);
            ++bad;
        }
        int has_start = v->causality == CAUSALITY_PARAMETER || v->causality == CAUSALITY_INPUT;
        if (has_start && !(v->start >= v->min && v->start <= v->max)) {
            fprintf(stderr, "%s variable %s: start %g outside [%g, %g]\n",
                    MODEL.identifier, v->name, v->start, v->min, v->max);
            ++bad;
        }
        if (has_start && !rt_value_fits(v->type, v->start)) {
            fprintf(stderr, "%s variable %s: start %g is not a %s value\n",
                    MODEL.identifier, v->name, v->start, rt_type_name(v->type));
            ++bad;
        }
        if (v->variability == VARIABILITY_DISCRETE && v->causality == CAUSALITY_PARAMETER) {
            fprintf(stderr, "%s variable %s: a parameter is FIXED or TUNABLE, not DISCRETE\n",
                    MODEL.identifier, v->name);
            ++bad;
        }
        for (size_t j = 0; j < i; ++j)
            if (strcmp(MODEL.variables[j].name, v->name) == 0) {
                fprintf(stderr, "%s variable %s: duplicate name\n", MODEL.identifier, v->name);
                ++bad;
            }
    }
    return bad;
}

int main(int argc, char **argv)
{
    if (argc < 2 || (strcmp(argv[1], "2") != 0 && strcmp(argv[1], "3") != 0)) {
        fprintf(stderr, "usage: %s 2|3 [source files...]\n", argv[0]);
        return 2;
    }
    if (check_table(argv[1][0] - '0')) return 1;
    if (argv[1][0] == '2') print_fmi2(argc - 2, argv + 2);
    else print_fmi3();
    return 0;
}
