"""The shipped scenarios: run by name from any folder (`cosim run lane_change`).

They are the YAML files of the platform's `scenarios/` folder (the checkout's,
or the copy an installed wheel carries: `cosim.resources`). A scenario
argument is a file when such a file exists, else the name of a shipped
scenario ("lane_change", or "lane_change.yaml"); anything else is a
`ScenarioError` that lists the shipped names, or, for a path that exists but
is no regular file (a directory, a FIFO, /dev/null), says what it is.
"""

from __future__ import annotations

import stat
from dataclasses import dataclass
from pathlib import Path

from cosim.errors import Problem, ScenarioError, did_you_mean
from cosim.resources import scenarios_dir

SUFFIXES = (".yaml", ".yml")
SUMMARY_CHARS = 90  # of the description, in the listing


@dataclass(frozen=True)
class ShippedScenario:
    """One shipped scenario: its name (the file's stem), file, and one-line summary."""

    name: str
    path: Path
    summary: str
    duration: float | None


def shipped_scenarios() -> dict[str, Path]:
    """Name -> file of every shipped scenario, sorted by name."""
    folder = scenarios_dir()
    if not folder.is_dir():
        return {}
    files = [p for p in folder.iterdir() if p.suffix in SUFFIXES and p.is_file()]
    return {p.stem: p for p in sorted(files, key=lambda p: p.stem)}


def describe_shipped() -> list[ShippedScenario]:
    """Every shipped scenario with the first sentence of its description and its duration."""
    import yaml

    found = []
    for name, path in shipped_scenarios().items():
        try:
            document = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
        except (OSError, yaml.YAMLError):
            document = {}
        text = " ".join(str(document.get("description", "")).split())
        summary = text.split(". ")[0].rstrip(".")
        if len(summary) > SUMMARY_CHARS:
            summary = summary[:SUMMARY_CHARS].rsplit(" ", 1)[0].rstrip(",;") + " ..."
        duration = document.get("duration")
        found.append(ShippedScenario(name, path, summary,
                                     float(duration) if isinstance(duration, (int, float)) else None))
    return found


def listing() -> str:
    """The shipped scenarios, one line each: name, duration, summary."""
    rows = describe_shipped()
    if not rows:
        return f"no shipped scenarios found in {scenarios_dir()}"
    width = max(len(r.name) for r in rows)
    lines = []
    for row in rows:
        duration = f"{row.duration:g} s" if row.duration is not None else "?"
        lines.append(f"{row.name:<{width}}  {duration:>6}  {row.summary}".rstrip())
    return "\n".join(lines)


def find_scenario(scenario: str | Path) -> Path:
    """The shipped scenario an argument names when no such file exists, else the argument as a path.

    Args:
        scenario: a path to a YAML file, or a shipped name ("lane_change").
    """
    path = Path(scenario)
    stem = path.stem if path.suffix in SUFFIXES else path.name
    if path.parent == Path(".") and not path.exists():
        return shipped_scenarios().get(stem, path)
    return path


#: what a path that exists but is no regular file is, by its stat.S_IFMT type
_FILE_KINDS = {stat.S_IFDIR: "a directory", stat.S_IFIFO: "a FIFO (named pipe)",
               stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
               stat.S_IFSOCK: "a socket"}


def not_a_file(path: Path) -> str | None:
    """What an existing path that is not a regular file is ("is a directory",
    "is a FIFO (named pipe)"); None for a regular file or no such path.
    The path is never opened (opening a FIFO would wait for a writer)."""
    try:
        mode = path.stat().st_mode
    except OSError:  # no such file (or no access): the caller's "not found"
        return None
    if stat.S_ISREG(mode):
        return None
    return "is " + _FILE_KINDS.get(stat.S_IFMT(mode), "no regular file")


def resolve_scenario(scenario: str | Path) -> Path:
    """The scenario file an argument names: an existing file, else a shipped scenario.

    Args:
        scenario: a path to a YAML file, or a shipped name ("lane_change").
    Raises:
        ScenarioError: neither a file nor a shipped name (the shipped names are listed).
    """
    path = find_scenario(scenario)
    if path.is_file():
        return path
    text = str(scenario)
    kind = not_a_file(path)
    if kind is not None:
        raise ScenarioError(text, [Problem("", None, f"{kind}, not a regular file")])
    shipped = shipped_scenarios()
    stem = path.stem if path.suffix in SUFFIXES else path.name
    names = ", ".join(shipped) or "none"
    hint = did_you_mean(stem, shipped) if path.parent == Path(".") else ""
    raise ScenarioError(text, [Problem("", None, f"scenario file not found, nor a shipped "
                                                 f"scenario{hint} (shipped: {names})")])
