"""After a run: its metrics and figures, computed one way for `cosim run` and `cosim.run`.

`analyse_run_folder` merges the platform's metrics (`cosim.analysis.metrics`)
into metrics.json beside what the components reported, refreshes the
RunResult's metrics from that file, and draws the figures. It reads every tick
from the recorder (`RunResult.full_signals`, its spool mapped: the values of
signals.csv, without parsing it back), so a decimated run (`record: {every: N}`)
is analysed from every tick too, not from its files.
Analysis is best effort after a run that itself succeeded: what
cannot be computed becomes a note, not an error.
"""

from __future__ import annotations

import json
from typing import Any


def analyse_run_folder(result: Any, figures: bool, drawer: Any = None) -> list[str]:
    """Merge the run metrics into metrics.json and draw the figures; notes to print.

    A run folder that cannot be analysed (e.g. a signals.csv that cannot be read)
    gives a note, not an error: the run itself succeeded.

    Args:
        result: a cosim.execution.run.RunResult (its metrics are refreshed from metrics.json).
        figures: draw the PNG figures too.
        drawer: a `cosim.execution.figure_process.FigureProcess` started with the run,
            which draws them (handed the run before the metrics are written, so both go
            on at once); None, or one that cannot take the run: drawn in this process.
    """
    from cosim.analysis.metrics import write_metrics
    from cosim.analysis.rundata import recorded_run

    full_signals = getattr(result, "full_signals", None)
    try:  # the recorder's rows, not signals.csv parsed back, for metrics and figures
        run = recorded_run(result.out_dir, full_signals)
    except Exception as exc:  # analysis is best effort after a run
        return [f"metrics not computed: {exc}"] + ([f"figures not drawn: {exc}"] if figures else [])
    handed = figures and drawer is not None and drawer.take(result.out_dir, full_signals)
    notes: list[str] = []
    try:
        write_metrics(result.out_dir, run=run)
        result.metrics = json.loads((result.out_dir / "metrics.json").read_text())
    except Exception as exc:
        notes.append(f"metrics not computed: {exc}")
    drawn = drawer.notes() if handed else None
    if drawn is not None:
        notes += drawn
    elif figures:  # no process, or one that could not draw: drawn here
        try:
            from cosim.figures.layouts import draw_figures

            notes += [f"figure: {path}" for path in draw_figures(result.out_dir, run=run)]
        except Exception as exc:
            notes.append(f"figures not drawn: {exc}")
    return notes
