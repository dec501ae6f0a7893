/*
 * xmlgen.c - build-time generator of modelDescription.xml (FMI 2.0 or 3.0).
 *
 * Compiled and linked with a model's code, so the variable table is read by
 * the compiler only: `xmlgen 2|3 [source files...]` prints the description of
 * MODEL on stdout; the source file names go into FMI2 <SourceFiles>.
 * Exits non-zero with a message on stderr for a unit it cannot express.
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

static void print_unit_definitions(void)
{
    const char *used[64];
    size_t n = 0;
    puts("  <UnitDefinitions>");
    for (size_t i = 0; i <= MODEL.n_variables; ++i) {
        const char *u = i < MODEL.n_variables ? MODEL.variables[i].unit : "s";
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
    return c == CAUSALITY_PARAMETER ? "parameter" : (c == CAUSALITY_INPUT ? "input" : "output");
}

static const char *variability_name(const VariableInfo *v)
{
    if (v->causality != CAUSALITY_PARAMETER) return "continuous";
    return v->variability == VARIABILITY_TUNABLE ? "tunable" : "fixed";
}

static const char *initial_attribute(const VariableInfo *v)
{
    if (v->causality == CAUSALITY_PARAMETER) return " initial=\"exact\"";
    return v->causality == CAUSALITY_OUTPUT ? " initial=\"calculated\"" : "";
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

/* Attributes common to FMI2 <Real> and FMI3 <Float64>: unit, start, min, max. */
static void print_value_attributes(const VariableInfo *v)
{
    printf(" unit=\"%s\"", v->unit);
    if (v->causality != CAUSALITY_OUTPUT) print_double("start", v->start);
    if (isfinite(v->min)) print_double("min", v->min);
    if (isfinite(v->max)) print_double("max", v->max);
}

static void print_header(int version)
{
    puts("<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    printf("<fmiModelDescription fmiVersion=\"%s\" modelName=\"%s\" %s=\"%s\"\n  description=\"",
           version == 2 ? "2.0" : "3.0", MODEL.identifier,
           version == 2 ? "guid" : "instantiationToken", MODEL.guid);
    print_escaped(MODEL.description);
    printf("\"\n  generationTool=\"cosim fmu_build (xmlgen.c)\" variableNamingConvention=\"flat\"%s>\n",
           version == 2 ? " numberOfEventIndicators=\"0\"" : "");
}

static void print_fmi2(int argc, char **argv)
{
    print_header(2);
    printf("  <CoSimulation modelIdentifier=\"%s\" canHandleVariableCommunicationStepSize=\"true\"\n"
           "    canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\""
           " canNotUseMemoryManagementFunctions=\"true\">\n    <SourceFiles>\n", MODEL.identifier);
    for (int i = 0; i < argc; ++i) printf("      <File name=\"%s\"/>\n", argv[i]);
    puts("    </SourceFiles>\n  </CoSimulation>");
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
        printf("\"\n      causality=\"%s\" variability=\"%s\"%s>\n      <Real",
               causality_name(v->causality), variability_name(v), initial_attribute(v));
        print_value_attributes(v);
        puts("/>\n    </ScalarVariable>");
    }
    puts("  </ModelVariables>\n  <ModelStructure>\n    <Outputs>");
    print_outputs("      ", "Unknown", "index", 1);
    puts("    </Outputs>\n    <InitialUnknowns>");
    print_outputs("      ", "Unknown", "index", 1);
    puts("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>");
}

static void print_fmi3(void)
{
    print_header(3);
    printf("  <CoSimulation modelIdentifier=\"%s\" canHandleVariableCommunicationStepSize=\"true\"\n"
           "    canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" hasEventMode=\"false\""
           " providesIntermediateUpdate=\"false\"/>\n", MODEL.identifier);
    print_unit_definitions();
    print_log_categories();
    printf("  <DefaultExperiment startTime=\"0\"");
    print_double("stepSize", MODEL.default_step);
    printf("/>\n  <ModelVariables>\n    <Float64 name=\"time\" valueReference=\"%u\""
           " causality=\"independent\" variability=\"continuous\" unit=\"s\""
           " description=\"simulation time\"/>\n", RT_VR_TIME);
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        printf("    <Float64 name=\"%s\" valueReference=\"%u\" description=\"", v->name, (unsigned)i);
        print_escaped(v->description);
        printf("\"\n      causality=\"%s\" variability=\"%s\"%s", causality_name(v->causality),
               variability_name(v), initial_attribute(v));
        print_value_attributes(v);
        puts("/>");
    }
    puts("  </ModelVariables>\n  <ModelStructure>");
    print_outputs("    ", "Output", "valueReference", 0);
    print_outputs("    ", "InitialUnknown", "valueReference", 0);
    puts("  </ModelStructure>\n</fmiModelDescription>");
}

/* Reject what the XML could not express faithfully. */
static int check_table(void)
{
    int bad = 0;
    for (size_t i = 0; i < MODEL.n_variables; ++i) {
        const VariableInfo *v = &MODEL.variables[i];
        if (!find_unit(v->unit)) {
            fprintf(stderr, "%s variable %s: unknown unit '%s' (add it to UNITS in xmlgen.c)\n",
                    MODEL.identifier, v->name, v->unit);
            ++bad;
        }
        if (v->causality != CAUSALITY_OUTPUT && !(v->start >= v->min && v->start <= v->max)) {
            fprintf(stderr, "%s variable %s: start %g outside [%g, %g]\n",
                    MODEL.identifier, v->name, v->start, v->min, v->max);
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
    if (check_table()) return 1;
    if (argv[1][0] == '2') print_fmi2(argc - 2, argv + 2);
    else print_fmi3();
    return 0;
}
