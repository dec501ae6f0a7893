/*
 * variable_table.h - optional helper for model code: expands the model's
 * variables.def (found on the include path) into
 *   - the enum of value references  VR_<ident> (0, 1, 2, ... in table order)
 *     and VR_COUNT;
 *   - MODEL_VARIABLE_TABLE_ROW (VAR lines, Float64) and
 *     MODEL_TYPED_VARIABLE_TABLE_ROW (TVAR lines), the X-macro bodies for the
 *     VariableInfo array:
 *       static const VariableInfo VARIABLES[] = {
 *       #define VAR MODEL_VARIABLE_TABLE_ROW
 *       #define TVAR MODEL_TYPED_VARIABLE_TABLE_ROW
 *       #include "variables.def"
 *       #undef VAR
 *       #undef TVAR
 *       };
 *     (a table with VAR lines only may leave TVAR undefined).
 * Include it after model.h and <math.h> (the table may use INFINITY).
 */
#ifndef COSIM_VARIABLE_TABLE_H
#define COSIM_VARIABLE_TABLE_H

#include "model.h"

typedef enum {
#define VAR(ident, causality, variability, unit, start, min, max, description) VR_##ident,
#define TVAR(type, ident, causality, variability, unit, start, min, max, description) VR_##ident,
#include "variables.def"
#undef VAR
#undef TVAR
    VR_COUNT
} ValueReference;

#define MODEL_TYPED_VARIABLE_TABLE_ROW(type, ident, causality, variability, unit, start, min, \
                                       max, description)                                    \
    { #ident, CAUSALITY_##causality, VARIABILITY_##variability, unit, start, min, max,         \
      description, TYPE_##type },

#define MODEL_VARIABLE_TABLE_ROW(ident, causality, variability, unit, start, min, max, description) \
    MODEL_TYPED_VARIABLE_TABLE_ROW(FLOAT64, ident, causality, variability, unit, start, min, max, \
                                   description)

#endif
