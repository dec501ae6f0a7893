"""The analysis commands of `cosim`: plot, compare, sweep.

`register(app)` adds them to the main typer app (cosim/cli.py):

    cosim plot RUN_DIR [--layout track|manoeuvre]
    cosim compare RUN_DIR RUN_DIR ... [--out DIR]
    cosim sweep SCENARIO --vary PATH=LOW:HIGH ... --samples N [--seed S] [--set PATH=VALUE ...]
                [--scheduler ADDRESS] [--out DIR] [--transport inproc|zenoh] [--method lhs|uniform]

A user error (missing run folder, bad --vary, unreachable scheduler) prints
one line on stderr and exits with status 2, without a traceback.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from cosim.cli_common import user_error_exit as _fail
from cosim.errors import UserError


def plot(run_dir: Path = typer.Argument(..., help="run folder"),
         layout: Optional[str] = typer.Option(None, "--layout",
                                              help="track | manoeuvre (default: from the scenario)")
         ) -> None:
    """Redraw the paper-style figure of a run into its folder."""
    from cosim.figures import draw_figures

    try:
        paths = draw_figures(run_dir, layout)
    except UserError as exc:
        raise _fail(exc) from None
    for path in paths:
        typer.echo(f"figure: {path}")


def compare(run_dirs: list[Path] = typer.Argument(..., help="two or more run folders"),
            out: Optional[Path] = typer.Option(None, "--out",
                                               help="output folder (default: <first run's parent>/compare)"),
            layout: Optional[str] = typer.Option(None, "--layout", help="track | manoeuvre")
            ) -> None:
    """Overlay several runs' figures and tabulate their metrics side by side."""
    from cosim.compare import compare_runs

    out_dir = out if out is not None else Path(run_dirs[0]).resolve().parent / "compare"
    try:
        paths = compare_runs(run_dirs, out_dir, layout)
    except UserError as exc:
        raise _fail(exc) from None
    typer.echo(paths[2].read_text(), nl=False)
    for path in paths:
        typer.echo(f"wrote: {path}")


def _print_summary(result) -> None:
    from cosim.sweep import STATS

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


def sweep(scenario: Path = typer.Argument(..., help="scenario YAML file"),
          vary: list[str] = typer.Option(..., "--vary", help="PATH=LOW:HIGH, repeatable"),
          sets: Optional[list[str]] = typer.Option(None, "--set",
                                                   help="PATH=VALUE fixed for every sample, repeatable"),
          samples: int = typer.Option(..., "--samples", help="number of sampled runs"),
          seed: int = typer.Option(0, "--seed", help="sampling seed"),
          scheduler: Optional[str] = typer.Option(None, "--scheduler",
                                                  help="Dask scheduler address (default: a local cluster)"),
          out: Optional[Path] = typer.Option(None, "--out",
                                             help="output folder (default: runs/sweep-<name>-s<seed>-n<samples>)"),
          transport: str = typer.Option("inproc", "--transport", help="inproc | zenoh, for each run"),
          method: str = typer.Option("lhs", "--method", help="lhs | uniform")) -> None:
    """Monte-Carlo runs of a scenario on Dask; the distribution of every metric."""
    from cosim.sweep import run_sweep

    out_dir = out if out is not None else Path("runs") / f"sweep-{scenario.stem}-s{seed}-n{samples}"
    try:
        result = run_sweep(scenario, vary, samples, seed=seed, scheduler=scheduler,
                           out_dir=out_dir, transport=transport, method=method,
                           sets=sets or ())
    except UserError as exc:
        raise _fail(exc) from None
    _print_summary(result)
    if result.summary:
        from cosim.figures_sweep import draw_sweep_histograms

        typer.echo(f"figure: {draw_sweep_histograms(result)}")
    typer.echo(f"results: {result.out_dir}")


def register(app: typer.Typer) -> None:
    """Add the plot, compare and sweep commands to the `cosim` app.

    Args:
        app: the main typer application.
    """
    app.command("plot")(plot)
    app.command("compare")(compare)
    app.command("sweep")(sweep)
