"""User-facing errors of the whole platform.

Every error a user can cause by what they wrote or gave us (a scenario file,
an FMU, a component that fails mid-run) derives from `UserError`. The CLI
prints `str(error)` without a traceback and exits with status 2; anything that
is not a `UserError` is a bug of the platform and keeps its traceback.

Errors about a file list every problem at once, one per line, in the form
`FILE:LINE: PATH: MESSAGE` (the line is left out when unknown, the path when
the problem is about the whole file).
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path


class UserError(Exception):
    """Base of every error caused by user input; shown as is, without traceback."""


def did_you_mean(name: str, candidates: Iterable[str], n: int = 1) -> str:
    """A spelling hint for a message: " (did you mean 'x'?)", or "" when nothing is close.

    Args:
        name: the misspelt name.
        candidates: the valid names, in the order to prefer among equally close ones.
        n: how many close names to offer at most.
    """
    close = difflib.get_close_matches(name, list(candidates), n=n)
    return f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""


@dataclass(frozen=True)
class Problem:
    """One problem found in a file.

    Args:
        path: dotted path of the field in the document, e.g.
            "components.controller.period" or "connections[2]"; "" for the file.
        line: 1-based line in the file, or None when unknown (e.g. a value set
            on the command line).
        message: what is wrong, naming the offending value.
    """

    path: str
    line: int | None
    message: str

    def format(self, file: str | Path | None) -> str:
        """Render as "FILE:LINE: PATH: MESSAGE", leaving out unknown parts."""
        where = str(file) if file is not None else "<scenario>"
        if self.line is not None:
            where += f":{self.line}"
        if self.path:
            where += f": {self.path}"
        return f"{where}: {self.message}"


class ProblemsError(UserError):
    """A user error made of one or more located problems in one file.

    Attributes:
        file: the file the problems are in (None for an in-memory document).
        problems: every problem found, in document order where known.
    """

    def __init__(self, file: str | Path | None, problems: Sequence[Problem]):
        self.file = file
        self.problems: list[Problem] = list(problems)
        super().__init__(self._render())

    def _render(self) -> str:
        return "\n".join(p.format(self.file) for p in self.problems)

    def __str__(self) -> str:
        return self._render()


class ScenarioError(ProblemsError):
    """A scenario file is unreadable or invalid."""


class WiringError(ProblemsError):
    """The connections of a scenario do not fit the components' ports."""


class FmuInterfaceError(UserError):
    """An FMU cannot be used: not an FMU, wrong kind or version, bad names or parameters."""


class ComponentFailure(UserError):
    """A component crashed, hung past its deadline or produced a bad value mid-run.

    Args:
        component: the component's name in the scenario.
        tick: the master tick at which it failed (None: during initialization).
        time: the simulation time of that tick, in seconds.
        cause: what went wrong, e.g. "output 'delta' is NaN".
        details: machine-readable facts for the manifest's "cause", e.g.
            {"kind": "signal", "signal": "SIGSEGV"} for a process that died.
    """

    def __init__(self, component: str, tick: int | None, time: float, cause: str,
                 details: dict | None = None):
        self.component = component
        self.tick = tick
        self.time = time
        self.cause = cause
        self.details = dict(details or {})
        when = "during initialization" if tick is None else f"at tick {tick}"
        super().__init__(
            f"component {component!r} failed {when} (t={time:.10g} s): {cause}"
        )


class StartFault(ComponentFailure):
    """A component process died or hung before its handshake: a fault of the run, not of its
    input, so `cosim run` exits 1 ("run failed:"), as for a constructor that crashes or
    hangs in the master's process, not 2 as for a scenario or parameter mistake."""


class RunFolderError(UserError):
    """The run folder cannot be written: "cannot write the run folder X: <reason> at tick k".

    Args:
        folder: the run folder.
        reason: an OSError (its strerror is shown) or a text.
        tick: the tick being recorded, or None when not known.
    """

    def __init__(self, folder: str | Path, reason: OSError | str, tick: int | None = None) -> None:
        text = reason if isinstance(reason, str) else (reason.strerror or str(reason))
        super().__init__(f"cannot write the run folder {folder}: {text}"
                         + (f" at tick {tick}" if tick is not None else ""))


class StopRequested(Exception):
    """A component asks to end the run normally after its step (an FMU's termination request).

    Raised by a host's `step` with the outputs of the step that asked: the
    master records that tick, then ends the run with status ok and
    `stopped_by` naming the component and the time.

    Args:
        component: the component's name in the scenario.
        tick: the master tick whose step asked to stop.
        time: the simulation time of that tick, in seconds.
        outputs: the component's outputs of that step.
        reason: why, in the component's words.
    """

    def __init__(self, component: str, tick: int, time: float, outputs: dict, reason: str):
        self.component, self.tick, self.time = component, tick, time
        self.outputs, self.reason = outputs, reason
        super().__init__(f"component {component!r} asked to stop the run at tick {tick} "
                         f"(t={time:.10g} s): {reason}")
