"""An SSP system as a scenario document, alone or merged into a YAML's (`system: file.ssp`).

`ssp_scenario` makes the whole document of `cosim run system.ssp`: its lines
are those of the package's SystemStructure.ssd, so later messages (FMU
parameters, wiring) point into it. `merge_system` brings an SSP's components
and connections into a YAML document, ahead of the YAML's own (which may add
Python components, sources and connections to the FMUs); the YAML's name and
timing win, the SSP's fill what the YAML leaves out. Entries that came from
the SSP carry the line of the YAML's `system:` key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from cosim.errors import Problem
from cosim.scenario.yaml_lines import LineMap

SSP_SUFFIXES = (".ssp", ".ssd")
TIMING = ("name", "duration", "tick", "start_time")


def is_ssp(path: str | Path) -> bool:
    """True for a file that `load_scenario` reads as an SSP package."""
    return Path(path).suffix.lower() in SSP_SUFFIXES


def ssp_scenario(path: Path) -> tuple[dict[str, Any], LineMap]:
    """The scenario document of an SSP package and the .ssd lines of its entries.

    Raises:
        ScenarioError: the package's problems (member, line, element each).
    """
    from cosim.scenario.ssp import read_system, system_document

    system = read_system(path)
    return system_document(system), LineMap(lines=dict(system.lines))


def merge_system(data: dict[str, Any], base_dir: Path, lines: LineMap) -> list[Problem]:
    """Merge the SSP that `data["system"]` names into `data`, in place; the problems found.

    Args:
        data: the YAML document (its `system` key is set to None once merged).
        base_dir: folder the system path resolves against.
        lines: the document's line map; YAML connection lines move down by the
            number of SSP connections put in front of them.
    Raises:
        ScenarioError: the SSP package's own problems.
    """
    from cosim.scenario.ssp import read_system, system_document

    where = lines.line_of(("system",))
    value = data.get("system")
    if not isinstance(value, str) or not is_ssp(value):
        return [Problem("system", where, f"system must be the path of an .ssp or .ssd file "
                                         f"(got {value!r})")]
    path = Path(value) if Path(value).is_absolute() else base_dir / value
    system = system_document(read_system(path))
    data["system"] = None
    problems = []
    for key in TIMING:
        if key not in data and key in system:
            data[key] = system[key]
    own = data.get("components") if isinstance(data.get("components"), dict) else {}
    for name in own:
        if name in system["components"]:
            problems.append(Problem(f"components.{name}", lines.line_of(("components", name)),
                                    f"name {name!r} is already a component of {value}"))
    data["components"] = {**system["components"],
                          **{k: v for k, v in own.items() if k not in system["components"]}}
    for name in system["components"]:
        lines.lines[("components", name)] = where
    connections = data.get("connections") if isinstance(data.get("connections"), list) else []
    _shift_connection_lines(lines, len(system["connections"]), where)
    data["connections"] = system["connections"] + connections
    return problems


def _shift_connection_lines(lines: LineMap, count: int, where: int | None) -> None:
    """Move the YAML's connection lines down by `count` entries; the first `count` at `where`."""
    moved = {}
    for key, line in lines.lines.items():
        if len(key) >= 2 and key[0] == "connections" and isinstance(key[1], int):
            moved[("connections", key[1] + count, *key[2:])] = line
        else:
            moved[key] = line
    moved.update({("connections", i): where for i in range(count) if where is not None})
    lines.lines = moved
