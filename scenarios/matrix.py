"""Results matrix: every scenario x controller x plant, run in-process, as a table.

    python -m scenarios.matrix --out DIR [--scenario NAME ...] [--controller NAME ...]
                               [--plant NAME ...] [--set PATH=VALUE ...]
    python -m scenarios.matrix --out DIR --write-docs    # and rewrite the READMEs' tables

Each combination is the scenario file with two overrides: the plant
(`components.vehicle.fmu`) and the controller component (the whole
`components.controller` entry, one of CONTROLLERS). A scenario without a
`controller` component (open_loop) runs once per plant. Each run gets its own
folder DIR/runs/<scenario>-<controller>-<plant>; the table goes to
DIR/results.csv and DIR/results.md (markdown), one row per run with the
metrics of cosim.analysis.metrics and the run's status. A run that fails (the vehicle
leaves the road, a component error) is a row with status "failed" and its
message, not an abort: the matrix is there to show such failures.

CONTROLLERS holds the controller lines the scenario files list as comments
under their `controller:` line; tests/scenarios/test_shipped.py checks they agree.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

SCENARIO_DIR = Path(__file__).resolve().parent
PLANTS = ("Vehicle8DOF", "Bicycle")
BACKSTEPPING = "controllers.backstepping:BacksteppingController"

#: controller name -> the scenario's `components.controller` entry. The first
#: is the one the scenario files run; the files list the others as comments.
CONTROLLERS: dict[str, dict] = {
    "bs_robust_ff": {"python": BACKSTEPPING, "period": 0.01, "parameters": {
        "adaptive": True, "adaptation": "robust", "lateral_law": "feedforward", "mu0": 0.8,
        "mu_min": 0.3, "ke": 4.0, "kz": 20.0}},
    "bs_adaptive_ff": {"python": BACKSTEPPING, "period": 0.01, "parameters": {
        "adaptive": True, "lateral_law": "feedforward", "mu0": 0.8, "mu_min": 0.3, "ke": 4.0,
        "kz": 20.0}},
    "bs_adaptive_faithful": {"python": BACKSTEPPING, "period": 0.01, "parameters": {
        "adaptive": True, "lateral_law": "faithful", "mu0": 0.8, "mu_min": 0.3, "ke": 4.0,
        "kz": 20.0}},
    "bs_faithful": {"python": BACKSTEPPING, "period": 0.01, "parameters": {
        "adaptive": False, "lateral_law": "faithful", "mu0": 1.0, "ke": 4.0, "kz": 20.0}},
    "stanley": {"python": "controllers.baselines:StanleyController", "period": 0.01,
                "parameters": {}},
    "pure_pursuit": {"python": "controllers.baselines:PurePursuitController", "period": 0.01,
                     "parameters": {}},
}
NO_CONTROLLER = "none"
COLUMNS = ("rms_yc", "max_abs_yc", "rms_yc_cg", "max_abs_yc_cg", "rms_yL", "rms_psiL", "max_abs_psiL", "rms_ex", "max_abs_ex",
           "max_abs_delta", "max_abs_delta_rate", "max_abs_ay", "mu_true_final", "mu_hat_final",
           "cone_hits")



def _flow(value: object) -> str:
    """A value as YAML flow text (mappings, bools, numbers, plain strings)."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_flow(v)}" for k, v in value.items()) + "}"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def controller_line(name: str) -> str:
    """The one YAML line `controller: {...}` of a CONTROLLERS entry (as the files hold it).

    Args:
        name: a CONTROLLERS key.
    """
    return f"controller: {_flow(CONTROLLERS[name])}"

@dataclass
class MatrixRow:
    """One run of the matrix: what was run, how it ended, its metrics."""

    scenario: str
    controller: str
    plant: str
    status: str
    error: str = ""
    wall_s: float = 0.0
    metrics: dict[str, float] = field(default_factory=dict)


def scenario_files(names: Sequence[str] = ()) -> list[Path]:
    """The scenario YAMLs of this folder, sorted, optionally only the named ones.

    Args:
        names: scenario file stems (e.g. "lane_change"); empty: all.
    Raises:
        SystemExit naming an unknown scenario.
    """
    files = sorted(SCENARIO_DIR.glob("*.yaml"))
    if not names:
        return files
    by_name = {f.stem: f for f in files}
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise SystemExit(f"unknown scenario(s) {', '.join(unknown)} "
                         f"(known: {', '.join(sorted(by_name))})")
    return [by_name[n] for n in names]


def has_controller(path: Path) -> bool:
    """True when the scenario file declares a `controller` component."""
    from cosim.scenario.loader import load_scenario

    return "controller" in load_scenario(path).components


def combination_overrides(controller: str, plant: str) -> list[str]:
    """The --set overrides that put `plant` and `controller` into a scenario.

    Args:
        controller: a CONTROLLERS key, or NO_CONTROLLER to leave the file's as is.
        plant: a built-in FMU name (PLANTS).
    """
    overrides = [f"components.vehicle.fmu={plant}"]
    if controller != NO_CONTROLLER:
        overrides.append(f"components.controller={json.dumps(CONTROLLERS[controller])}")
    return overrides


def run_one(path: Path, controller: str, plant: str, out_dir: Path,
            extra: Sequence[str] = ()) -> MatrixRow:
    """Run one combination in-process and compute its metrics.

    Args:
        path: the scenario file.
        controller: a CONTROLLERS key or NO_CONTROLLER.
        plant: a built-in FMU name.
        out_dir: the run folder.
        extra: further overrides (e.g. "duration=20"), applied last.
    Returns:
        the row; status "failed" with the message when the run failed.
    """
    from cosim.errors import UserError
    from cosim.analysis.metrics import compute_metrics
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    row = MatrixRow(path.stem, controller, plant, "ok")
    started = time.perf_counter()
    try:
        scenario = load_scenario(path, combination_overrides(controller, plant) + list(extra))
        result = run_scenario(scenario, out_dir, transport="inproc", progress=False)
        if result.status != "ok":
            row.status, row.error = "failed", str(result.error)
        row.metrics = compute_metrics(out_dir)
    except UserError as error:
        row.status, row.error = "failed", str(error)
    row.wall_s = time.perf_counter() - started
    return row


def combinations(files: Sequence[Path], controllers: Sequence[str],
                 plants: Sequence[str]) -> list[tuple[Path, str, str]]:
    """(file, controller, plant) for every run of the matrix, in table order."""
    combos = []
    for path in files:
        names = controllers if has_controller(path) else [NO_CONTROLLER]
        combos += [(path, c, p) for c in names for p in plants]
    return combos


def _cell(value: float | int | None) -> str:
    """A metric as table text ("" when missing)."""
    if value is None:
        return ""
    return str(value) if isinstance(value, int) else f"{value:.4g}"


def markdown_rows(rows: Sequence[MatrixRow]) -> list[str]:
    """The full results table as markdown lines (header, rule, one line per run).

    Columns: the metrics of COLUMNS that some row has, in that order.
    """
    shown = [c for c in COLUMNS if any(c in r.metrics for r in rows)]
    return (["| " + " | ".join(["scenario", "controller", "plant", "status", *shown]) + " |",
             "|" + "---|" * (4 + len(shown))] + [row_line(r, shown) for r in rows])


def row_line(row: MatrixRow, columns: Sequence[str]) -> str:
    """One run as a markdown table line with the given metric columns."""
    status = row.status if row.status == "ok" else f"failed: {row.error[:80]}"
    return "| " + " | ".join([row.scenario, row.controller, row.plant, status,
                              *(_cell(row.metrics.get(c)) for c in columns)]) + " |"


def write_tables(rows: Sequence[MatrixRow], out: Path) -> tuple[Path, Path]:
    """Write results.csv and results.md into `out`; returns their paths.

    Args:
        rows: the matrix rows.
        out: the folder (created).
    """
    out.mkdir(parents=True, exist_ok=True)
    head = ["scenario", "controller", "plant", "status", *COLUMNS, "wall_s", "error"]
    csv_path, md_path = out / "results.csv", out / "results.md"
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(head)
        for r in rows:
            writer.writerow([r.scenario, r.controller, r.plant, r.status,
                             *(repr(r.metrics[c]) if c in r.metrics else "" for c in COLUMNS),
                             f"{r.wall_s:.3f}", r.error])
    lines = markdown_rows(rows)
    md_path.write_text("\n".join(lines) + "\n")
    return csv_path, md_path


def run_matrix(out: Path, scenarios: Sequence[str] = (), controllers: Sequence[str] = (),
               plants: Sequence[str] = (), extra: Sequence[str] = (),
               echo: bool = True) -> list[MatrixRow]:
    """Run the selected combinations and write the tables.

    Args:
        out: output folder (runs/ and the tables go there).
        scenarios, controllers, plants: selections (empty: all).
        extra: overrides applied to every run.
        echo: print one line per run as it ends.
    """
    unknown = [c for c in controllers if c not in CONTROLLERS]
    if unknown:
        raise SystemExit(f"unknown controller(s) {', '.join(unknown)} "
                         f"(known: {', '.join(CONTROLLERS)})")
    bad_plants = [p for p in plants if p not in PLANTS]
    if bad_plants:
        raise SystemExit(f"unknown plant(s) {', '.join(bad_plants)} (known: {', '.join(PLANTS)})")
    rows = []
    for path, ctrl, plant in combinations(scenario_files(scenarios),
                                          list(controllers) or list(CONTROLLERS),
                                          list(plants) or list(PLANTS)):
        row = run_one(path, ctrl, plant, out / "runs" / f"{path.stem}-{ctrl}-{plant}", extra)
        rows.append(row)
        write_tables(rows, out)
        if echo:
            print(f"{row.scenario:20s} {row.controller:15s} {row.plant:12s} {row.status:6s} "
                  f"{row.wall_s:6.1f} s  " + " ".join(f"{k}={_cell(v)}" for k, v in
                                                      row.metrics.items() if k in COLUMNS[:6])
                  + (f"  {row.error[:200]}" if row.error else ""), flush=True)
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status (1 if any run failed).

    Args:
        argv: arguments (default: sys.argv[1:]).
    """
    parser = argparse.ArgumentParser(prog="python -m scenarios.matrix", description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--scenario", action="append", default=[], help="scenario name (repeatable)")
    parser.add_argument("--controller", action="append", default=[],
                        help=f"controller (repeatable): {', '.join(CONTROLLERS)}")
    parser.add_argument("--plant", action="append", default=[], help=f"plant: {', '.join(PLANTS)}")
    parser.add_argument("--set", dest="extra", action="append", default=[],
                        help="override PATH=VALUE applied to every run (repeatable)")
    parser.add_argument("--write-docs", action="store_true",
                        help="run everything and rewrite the generated tables of README.md and "
                             "scenarios/README.md (no selection or --set allowed)")
    args = parser.parse_args(argv)
    if args.write_docs and (args.scenario or args.controller or args.plant or args.extra):
        parser.error("--write-docs runs the whole matrix: no --scenario, --controller, --plant or --set")
    rows = run_matrix(args.out, args.scenario, args.controller, args.plant, args.extra)
    print(f"tables: {args.out / 'results.md'}, {args.out / 'results.csv'}")
    if args.write_docs:
        from scenarios import doc_tables

        variants = doc_tables.run_satory_variants(args.out)
        for path in doc_tables.write_docs(doc_tables.blocks(rows, variants)):
            print(f"rewrote the generated tables of {path}")
    return 1 if any(r.status != "ok" for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
