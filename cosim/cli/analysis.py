"""The analysis commands of `cosim`: plot, compare, sweep.

`register(app)` adds them to the main typer app (cosim/cli/app.py):

    cosim plot RUN_DIR [--layout track|manoeuvre|speed|following|signals]
               [--signals PATTERN ...] [--out FILE]
    cosim compare RUN_DIR [RUN_DIR ...] [--out DIR]
    cosim sweep SCENARIO --vary PATH=LOW:HIGH ... --samples N [--seed S] [--set PATH=VALUE ...]
                [--scheduler ADDRESS] [--out DIR [--force]] [--transport inproc|zenoh]
                [--method lhs|uniform]

Their default outputs go to comparisons/ and sweeps/, not runs/, so that
`cosim compare runs/*` sees only run folders; compare skips, with a note, an
argument that is a compare or sweep output folder.

A user error (missing run folder, bad --vary, --seed, --samples (1..100000) or
--transport, a malformed or unreachable scheduler, an --out under a regular file or where
nothing can be written, a sweep's non-empty --out without --force, or with it one that is
not an earlier sweep's) prints one line on stderr and exits with status 2, without a
traceback. A missing --out folder is created, with its parents. Ctrl-C during a sweep
prints "sweep interrupted after N of M samples; finished ones indexed in DIR" and exits 1.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from cosim.cli.common import user_error_exit as _fail
from cosim.errors import UserError
from cosim.results.folders import stamped_folder


def plot(run_dir: Path = typer.Argument(..., help="run folder"),
         layout: Optional[str] = typer.Option(
             None, "--layout", help="track | manoeuvre | speed | following | signals "
                                    "(default: from the scenario; signals for a run that "
                                    "is not a vehicle run)"),
         signals: Optional[list[str]] = typer.Option(
             None, "--signals", help="draw these recorded signals against time instead, one panel each "
                                     "with its unit: a glob over component.signal, quoted "
                                     "(repeatable: --signals 'ball.*' --signals '*.vx')"),
         out: Optional[Path] = typer.Option(
             None, "--out", help="PNG file to write, its folder created if missing "
                                 "(default: RUN_DIR/figure_<layout>.png)"),
         ) -> None:
    """Redraw the figure of a run: paper-style for a vehicle run, else its signals against time.

    Examples:

        cosim plot runs/lane_change-20260101T120000Z

        cosim plot RUN_DIR --signals 'ball.*' --out /tmp/ball.png
    """
    from cosim.analysis.outputs import check_output_file
    from cosim.analysis.rundata import load_run
    from cosim.figures.layouts import draw_figures

    try:
        if out is not None:
            check_output_file(out, f"--out {out}")
        paths = draw_figures(run_dir, layout, run=load_run(run_dir), signals=signals or (), out=out)
    except UserError as exc:
        raise _fail(exc) from None
    for path in paths:
        typer.echo(f"figure: {path}")


COMPARE_OUTPUTS = "comparisons"  # default parent of `cosim compare` outputs
SWEEP_OUTPUTS = "sweeps"  # default parent of `cosim sweep` outputs
# files that mark a folder as a compare or a sweep output, not a run folder
_OUTPUT_MARKERS = {"compare_metrics.csv": "a cosim compare output", "sweep.json": "a cosim sweep output"}


def output_folder_kind(folder: Path) -> str | None:
    """"a cosim compare output" / "a cosim sweep output" for such a folder, else None.

    Args:
        folder: a folder given to `cosim compare`.
    """
    for marker, kind in _OUTPUT_MARKERS.items():
        if (Path(folder) / marker).is_file():
            return kind
    return None


def compare(run_dirs: list[Path] = typer.Argument(
                ..., help="one or more run folders (compare and sweep outputs are skipped)"),
            out: Optional[Path] = typer.Option(
                None, "--out", help="output folder, created if missing "
                                    "(default: comparisons/compare-<UTC time>)"),
            layout: Optional[str] = typer.Option(
                None, "--layout", help="track | manoeuvre | speed (Fig. 4.3/4.4: one column per run) | following "
                                     "| signals (every signal against time)")
            ) -> None:
    """Overlay one or more runs' figures and tabulate their metrics side by side."""
    from cosim.analysis.outputs import check_folder
    from cosim.figures.compare import compare_runs

    runs = []
    for folder in run_dirs:
        kind = output_folder_kind(folder)
        if kind is None:
            runs.append(folder)
        else:
            typer.echo(f"skipped {folder}: {kind}, not a run folder", err=True)
    if not runs:
        raise _fail(UserError("compare: no run folder among the arguments "
                              f"({', '.join(str(d) for d in run_dirs)})"))
    out_dir = out if out is not None else stamped_folder(COMPARE_OUTPUTS, "compare")
    try:
        check_folder(out_dir, None if out is None else f"--out {out}")
        paths = compare_runs(runs, out_dir, layout)
    except UserError as exc:
        raise _fail(exc) from None
    typer.echo(paths[2].read_text(), nl=False)
    for path in paths:
        typer.echo(f"wrote: {path}")


def _print_summary(result) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from cosim.execution.sweep import STATS

    table = Table(title=f"sweep: {len(result.samples)} samples, {len(result.failures)} failed")
    table.add_column("metric", no_wrap=True)
    for stat in STATS:
        table.add_column(stat, justify="right")
    for name, stats in result.summary.items():
        table.add_row(name, str(int(stats["n"])), *(f"{stats[k]:.4g}" for k in STATS[1:]))
    console = Console()
    if not console.is_terminal:
        console = Console(width=160)  # a pipe or a file: do not squeeze the table to 80 columns
    console.print(table)
    for failure in result.failures:
        console.print(f"[yellow]failed:[/yellow] {escape(failure.error)}", markup=True, highlight=False)


def sweep(scenario: str = typer.Argument(..., help="scenario YAML file, or a shipped scenario's name"),
          vary: list[str] = typer.Option(..., "--vary", help="PATH=LOW:HIGH, repeatable"),
          sets: Optional[list[str]] = typer.Option(None, "--set",
                                                   help="PATH=VALUE fixed for every sample, repeatable"),
          samples: int = typer.Option(..., "--samples", help="number of sampled runs"),
          seed: int = typer.Option(0, "--seed", help="sampling seed"),
          scheduler: Optional[str] = typer.Option(None, "--scheduler",
                                                  help="Dask scheduler address (default: a local cluster)"),
          out: Optional[Path] = typer.Option(None, "--out",
                                             help="output folder (default: "
                                                  "sweeps/<name>-s<seed>-n<samples>-<UTC time>)"),
          transport: str = typer.Option("inproc", "--transport", help="inproc | zenoh, for each run"),
          method: str = typer.Option("lhs", "--method", help="lhs | uniform"),
          force: bool = typer.Option(False, "--force",
                                     help="replace an earlier sweep's --out folder (one with "
                                          "sweep.json or samples.csv)")) -> None:
    """Monte-Carlo runs of a scenario on Dask; the distribution of every metric.

    Example: cosim sweep lane_change --vary 'components.controller.parameters.ke=2:6' --samples 4
    """
    from cosim.analysis.outputs import check_folder
    from cosim.execution.sweep import SweepInterrupted, run_sweep
    from cosim.scenario.shipped import find_scenario

    scenario_file = find_scenario(scenario)
    out_dir = out if out is not None else stamped_folder(
        SWEEP_OUTPUTS, f"{scenario_file.stem}-s{seed}-n{samples}")
    try:
        check_folder(out_dir, None if out is None else f"--out {out}")
        result = run_sweep(scenario_file, vary, samples, seed=seed, scheduler=scheduler,
                           out_dir=out_dir, transport=transport, method=method,
                           sets=sets or (), force=force)
    except UserError as exc:
        raise _fail(exc) from None
    except SweepInterrupted as stop:  # Ctrl-C: the finished samples are indexed
        from rich.console import Console

        Console(stderr=True, highlight=False, soft_wrap=True).print(str(stop), markup=False)
        raise typer.Exit(1) from None
    _print_summary(result)
    if result.summary:
        from cosim.figures.sweep import draw_sweep_histograms

        typer.echo(f"figure: {draw_sweep_histograms(result)}")
    typer.echo(f"results: {result.out_dir}")
    if result.failures:  # the sweep is a failure unless every sample ran
        from rich.console import Console

        failed = ", ".join(str(f.index) for f in result.failures)
        Console(stderr=True, highlight=False, soft_wrap=True).print(
            f"[red]sweep failed:[/red] {len(result.failures)} of {len(result.samples)} samples "
            f"failed (samples {failed}; see samples.csv)", markup=True)
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add the plot, compare and sweep commands to the `cosim` app.

    Args:
        app: the main typer application.
    """
    app.command("plot")(plot)
    app.command("compare")(compare)
    app.command("sweep")(sweep)
