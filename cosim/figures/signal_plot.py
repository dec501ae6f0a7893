"""Recorded signals against time, one panel each: `cosim plot RUN --signals 'ball.*'`.

Also the figure of a run that is not a vehicle run (no component plays the vehicle,
controller or planner, cosim.scenario.roles): its first `DEFAULT_PANELS` signals.
Signals are chosen by fnmatch glob patterns over the scalar columns of signals.csv
("component.signal"), in the order of the patterns, then of the columns; each panel's
y axis carries the signal's unit from the manifest. Several runs are overlaid.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Sequence

from matplotlib.figure import Figure

from cosim.analysis.rundata import AnalysisError, RunData
from cosim.figures import panels as pan

DEFAULT_PANELS = 24     # the default figure of a run with many signals: `--signals` draws the others
LISTED_SIGNALS = 40     # a pattern that matches nothing names at most this many of the signals there are


def select_signals(run: RunData, patterns: Sequence[str]) -> list[str]:
    """The recorded scalar signals the patterns match, each once, in pattern order.

    Args:
        run: the run whose signals.csv columns are searched.
        patterns: fnmatch globs over "component.signal" ("ball.*", "*.vx").
    Raises:
        AnalysisError: a pattern matches no recorded signal (naming it and the signals there are).
    """
    chosen: dict[str, None] = {}
    for pattern in patterns:
        found = [name for name in run.columns if fnmatch.fnmatchcase(name, pattern)]
        if not found:
            names = list(run.columns)
            listed = ", ".join(names[:LISTED_SIGNALS]) or "none"
            more = f" and {len(names) - LISTED_SIGNALS} more" if len(names) > LISTED_SIGNALS else ""
            raise AnalysisError(f"{run.run_dir}: signal pattern {pattern!r} matches no recorded "
                                f"signal (recorded: {listed}{more})")
        chosen.update(dict.fromkeys(found))
    return list(chosen)


def signals_figure(runs: Sequence[RunData], names: Sequence[str], title: str) -> Figure:
    """One panel per signal against time, the runs overlaid; units from the first run's manifest.

    Args:
        runs: loaded runs (at least one).
        names: the "component.signal" columns to draw.
        title: the figure's title.
    """
    columns = 1 if len(names) <= 3 else 2 if len(names) <= 8 else 3
    rows = max(1, math.ceil(len(names) / columns))
    fig = Figure(figsize=(5.5 * columns + 1.0, 2.6 * rows + 0.8), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax, name in zip(axes, names):
        unit = runs[0].unit(name)
        description = str(runs[0].signal_info(name).get("description", "") or "")
        pan.time_series(ax, runs, lambda r, n=name: None if n not in r.columns else (r.time, r.columns[n]),
                        name, f"{name}: {description}" if description else name,
                        f"{name.split('.', 1)[-1]} ({unit})" if unit else name.split(".", 1)[-1])
    for ax in axes[len(names):]:
        ax.set_axis_off()
    fig.suptitle(title)
    return fig


def default_signals(run: RunData) -> tuple[list[str], str]:
    """The signals of a run's default signals figure, and a note on those left out ("" if none)."""
    names = list(run.columns)
    if len(names) <= DEFAULT_PANELS:
        return names, ""
    return names[:DEFAULT_PANELS], (f"the first {DEFAULT_PANELS} of {len(names)} signals; "
                                    "cosim plot RUN --signals 'PATTERN' draws any")
