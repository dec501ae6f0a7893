"""Comparison of several runs: overlaid paper-style panels and a metrics table.

`compare_runs(run_dirs, out_dir)` draws the figure layout of the first run with
every run overlaid (one colour per run, labelled by folder name, or by
parent/folder when two folders share a name; the tracking zoom goes to the
largest |yc_cg| of all runs, the map's road and obstacles are the first run's)
and writes the metrics of all runs side by side as CSV (exact values) and
Markdown (4 significant digits).
Metrics are the ones `cosim.analysis.metrics` computes, plus any other numbers the
run's components wrote into its metrics.json.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from pathlib import Path

from cosim.figures.layouts import build_figure, save_png
from cosim.analysis.metrics import analyse_run, ordered_metric_names
from cosim.analysis.outputs import check_folder, make_folder, write_failure
from cosim.analysis.rundata import AnalysisError, RunData, load_run, read_json_object


def run_labels(run_dirs: Sequence[Path]) -> list[str]:
    """Unique short labels: folder names, with the parent folder where names clash.

    Args:
        run_dirs: the run folders, in order.
    """
    names = [Path(d).resolve().name for d in run_dirs]
    labels = []
    for d, name in zip(run_dirs, names):
        resolved = Path(d).resolve()
        labels.append(name if names.count(name) == 1 else f"{resolved.parent.name}/{name}")
    if len(set(labels)) != len(labels):
        labels = [f"{i + 1}:{label}" for i, label in enumerate(labels)]
    return labels


def run_metrics(run: RunData) -> dict[str, float]:
    """The numeric entries of the run's metrics.json, updated with freshly computed metrics."""
    stored = read_json_object(run.run_dir / "metrics.json")
    merged = {k: v for k, v in stored.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    merged.update(analyse_run(run).values)
    return merged


def metrics_table(labels: Sequence[str], metrics: Sequence[dict[str, float]]
                  ) -> tuple[list[str], list[list[float | None]]]:
    """Rows of the comparison: metric names and, per name, one value per run (None: absent).

    The platform's metrics come first in their usual order, then other keys sorted.
    """
    present = set().union(*metrics) if metrics else set()
    names = ordered_metric_names(present)
    return names, [[m.get(n) for m in metrics] for n in names]


def _csv_text(labels: Sequence[str], names: list[str], rows: list[list[float | None]]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["metric", *labels])
    for name, row in zip(names, rows):
        writer.writerow([name, *("" if v is None else repr(v) for v in row)])
    return out.getvalue()


def _markdown_text(labels: Sequence[str], names: list[str], rows: list[list[float | None]]) -> str:
    lines = ["| metric | " + " | ".join(labels) + " |",
             "|---|" + "---:|" * len(labels)]
    for name, row in zip(names, rows):
        cells = ["-" if v is None else f"{v:.4g}" for v in row]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def compare_runs(run_dirs: Sequence[str | Path], out_dir: str | Path,
                 layout: str | None = None) -> list[Path]:
    """Overlay several runs and tabulate their metrics.

    Args:
        run_dirs: one or more run folders.
        out_dir: folder for the outputs (created if missing).
        layout: "track", "manoeuvre" or None to choose from the first run.

    Returns:
        The files written: compare_<layout>.png, compare_metrics.csv, compare_metrics.md.
    Raises:
        UserError: a run folder cannot be read, or the output folder cannot be made or
            written (a file in its place, no permission).
    """
    if not run_dirs:
        raise AnalysisError("compare: give at least one run folder")
    dirs = [Path(d) for d in run_dirs]
    runs = [load_run(d) for d in dirs]
    for run, label in zip(runs, run_labels(dirs)):
        run.label_override = label
    out = check_folder(out_dir)
    fig, layout = build_figure(runs, layout)
    png = save_png(fig, make_folder(out) / f"compare_{layout}.png")
    labels = [r.label for r in runs]
    names, rows = metrics_table(labels, [run_metrics(r) for r in runs])
    csv_path, md_path = out / "compare_metrics.csv", out / "compare_metrics.md"
    for path, text in ((csv_path, _csv_text(labels, names, rows)),
                       (md_path, _markdown_text(labels, names, rows))):
        try:
            path.write_text(text)
        except OSError as exc:
            raise write_failure(path, exc) from None
    return [png, csv_path, md_path]
