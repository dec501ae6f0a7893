"""The FMI variable types a signal can have, and which conversions between them are exact.

The master's signal store holds float64 values. Every type below except
Int64 and UInt64 (and FMI 3 Enumeration, read through the Int64 API) converts
exactly to float64; a 64-bit value that float64 cannot hold exactly (beyond
2^53) is a run failure naming the component, signal, tick and value, never a
silent rounding (`inexact_integer`). Python components' ports are Float64.

Connections (`cosim.engine.wiring`) accept a source whose values the
destination's type holds exactly (`exact_into`); any other pair needs
`convert: float` on the connection. A value written to an integer or Boolean
input must then be integer-valued and in that type's range (`integer_problem`),
else the run fails naming component, input, tick and value. Integer and
Boolean signals are written to the CSV files as integers (`is_integer`).
"""

from __future__ import annotations

FLOAT64 = "Float64"
FLOAT_TYPES = ("Real", "Float64")  # float64 in the store, as the FMU has it
EXACT_LIMIT = 2 ** 53  # every integer of at most this magnitude is a float64

#: integer-valued types -> (min, max) of their values
INTEGER_RANGES: dict[str, tuple[int, int]] = {
    "Boolean": (0, 1),
    "Int8": (-2 ** 7, 2 ** 7 - 1), "UInt8": (0, 2 ** 8 - 1),
    "Int16": (-2 ** 15, 2 ** 15 - 1), "UInt16": (0, 2 ** 16 - 1),
    "Int32": (-2 ** 31, 2 ** 31 - 1), "UInt32": (0, 2 ** 32 - 1),
    "Integer": (-2 ** 31, 2 ** 31 - 1),  # FMI 2 Integer and Enumeration: fmi2Integer (int)
    "Enumeration": (-2 ** 63, 2 ** 63 - 1),  # FMI 3: fmi3Int64; FMI 2: int (checked at run time)
    "Int64": (-2 ** 63, 2 ** 63 - 1), "UInt64": (0, 2 ** 64 - 1),
}
NUMERIC_TYPES = (*FLOAT_TYPES, "Float32", *INTEGER_RANGES)
NOT_RECORDED_TYPES = ("String", "Binary")  # listed once as not recorded
WIDE_TYPES = ("Int64", "UInt64")  # not exactly float64 beyond 2^53


def a_type(type_name: str) -> str:
    """The type name with its article, for messages: "an Int32", "a Float64"."""
    return f"{'an' if type_name[0] in 'AEIOU' else 'a'} {type_name}"


def is_integer(type_name: str) -> bool:
    """Whether a signal of this type holds integers (written to CSV as integers)."""
    return type_name in INTEGER_RANGES


def exact_into(source: str, destination: str) -> bool:
    """Whether every value of type `source` is held exactly by type `destination`.

    Args:
        source, destination: FMI type names ("Float64", "Int32", "Boolean", ...).
    """
    if destination in FLOAT_TYPES:
        return source not in WIDE_TYPES  # FMI 2 Enumeration is an int; FMI 3's is declared small
    if destination == "Float32":
        return source in ("Float32", "Boolean", "Int8", "UInt8", "Int16", "UInt16")
    if destination in INTEGER_RANGES and source in INTEGER_RANGES:
        if destination == "Boolean":
            return source == "Boolean"
        low, high = INTEGER_RANGES[destination]
        src_low, src_high = INTEGER_RANGES[source]
        return low <= src_low and src_high <= high
    return False


def integer_problem(value: float, type_name: str) -> str | None:
    """Why a store value cannot be written to an input of integer type, or None.

    Args:
        value: the float64 value the input reads.
        type_name: the input's type (a key of INTEGER_RANGES).
    """
    if value != value or value in (float("inf"), float("-inf")) or value != int(value):
        return f"is not an integer ({a_type(type_name)} input takes integer values only)"
    low, high = INTEGER_RANGES[type_name]
    if not low <= int(value) <= high:
        return f"is outside the range of {type_name} [{low}, {high}]"
    return None


def inexact_integer(value: int) -> bool:
    """Whether a 64-bit integer would be rounded in float64."""
    return abs(value) > EXACT_LIMIT and int(float(value)) != value


#: the README's rows: (FMI 2 / FMI 3 names, the types, what else happens)
TABLE_ROWS = (
    ("Real / Float64", ("Float64",), ""),
    ("Float32", ("Float32",), ""),
    ("Integer, Enumeration / Int8, UInt8, Int16, UInt16, Int32, UInt32, Enumeration",
     ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Enumeration"),
     "FMI 3 Enumeration is read as Int64: a value beyond 2^53 fails as for Int64"),
    ("Boolean / Boolean", ("Boolean",), ""),
    ("Int64, UInt64", WIDE_TYPES, "a value beyond 2^53 that float64 would round fails the run, "
     "naming component, signal, tick and value, exit 1"),
    ("String, Binary", NOT_RECORDED_TYPES, "one warning line at validate and run start; "
     "`not_recorded` in the manifest"),
)


def types_table() -> str:
    """The README's table of what happens to each FMI type (markdown)."""
    lines = ["| FMI type (FMI 2 / FMI 3) | in the CSV files | into a Float64 input | also |",
             "|---|---|---|---|"]
    for names, types, note in TABLE_ROWS:
        if not set(types) <= set(NUMERIC_TYPES):
            text, into = "not recorded", "cannot be connected"
        else:
            text = "integer" if all(map(is_integer, types)) else "repr of the float"
            exact = all(exact_into(t, FLOAT64) for t in types)
            into = "exact" if exact else "needs `convert: float`"
        lines.append(f"| {names} | {text} | {into} | {note} |")
    return "\n".join(lines) + "\n"
