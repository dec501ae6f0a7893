"""The closing summary of `cosim run`: a run table and a metrics table.

The run table gives status, ticks, times, the real-time factor, the time to
tick 0 and the pacing statistics; the metrics table lists the metrics of
`cosim.analysis.metrics` in their canonical order with unit and meaning (a run
that is not a vehicle run: the statistics of its signals, "max(ball.h)", with the
signal's unit from the manifest), then the metrics the components reported
("component.metric"). Values are rounded for
reading; metrics.json keeps them exact.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rich.console import Console
from rich.table import Table

# unit and quantity of each metric of cosim.analysis.metrics (METRIC_NAMES), in that order;
# the name's prefix says the statistic (rms_: time-weighted RMS, max_abs_: max |.|)
METRIC_INFO: dict[str, tuple[str, str]] = {
    "rms_yc": ("m", "lateral error at the CG, yL - ls psiL (paper, Fig. 4.7)"),
    "max_abs_yc": ("m", "lateral error at the CG, yL - ls psiL (paper, Fig. 4.7)"),
    "rms_yc_cg": ("m", "the CG's geometric offset from the path"),
    "max_abs_yc_cg": ("m", "the CG's geometric offset from the path"),
    "rms_yL": ("m", "lateral error at the preview point"),
    "max_abs_yL": ("m", "lateral error at the preview point"),
    "rms_psiL": ("rad", "heading error to the path"),
    "max_abs_psiL": ("rad", "heading error to the path"),
    "rms_ex": ("m/s", "speed error vx - vx_ref"),
    "max_abs_ex": ("m/s", "speed error vx - vx_ref"),
    "max_abs_delta": ("rad", "steering angle"),
    "max_abs_delta_rate": ("rad/s", "steering rate"),
    "max_abs_ay": ("m/s2", "lateral acceleration"),
    "mu_true_final": ("1", "road friction at the end"),
    "mu_hat_final": ("1", "friction estimate at the end"),
    "cone_hits": ("", "cones touched"),
    "rms_gap_error": ("m", "gap to the lead minus desired gap"),
    "max_abs_gap_error": ("m", "gap to the lead minus desired gap"),
    "min_time_gap": ("s", "smallest gap / speed (moving)"),
    "min_ttc": ("s", "smallest time to collision (closing in)"),
    "gap_overshoot": ("m", "deepest intrusion into the desired gap"),
    "collisions": ("", "contacts with the lead"),
}


# the meaning of each generic statistic (cosim.analysis.generic), before the signal's name
STATISTIC_INFO = {"min": "smallest value of", "max": "largest value of",
                  "rms": "time-weighted RMS of", "final": "value at the last tick of"}


def metric_rows(metrics: Mapping[str, Any], units: Mapping[str, str] | None = None
                ) -> list[tuple[str, str, str, str]]:
    """(name, value, unit, meaning) rows: known metrics in canonical order, then the rest.

    Args:
        metrics: metric name -> value (as in metrics.json).
        units: "component.signal" -> unit, for the generic statistics ("max(ball.h)").
    """
    from cosim.analysis.generic import parse_statistic_name
    from cosim.analysis.metrics import ordered_metric_names

    known = [n for n in METRIC_INFO if n in metrics]
    others = [n for n in ordered_metric_names(set(metrics)) if n not in METRIC_INFO]
    rows = []
    for name in known + others:
        statistic = parse_statistic_name(name)
        component = name.split(".")[0] if "." in name else None
        if statistic is not None:
            kind, signal = statistic
            unit, meaning = (units or {}).get(signal, ""), f"{STATISTIC_INFO[kind]} {signal}"
        else:
            unit, meaning = METRIC_INFO.get(name, ("", f"reported by {component}" if component else ""))
        rows.append((name, format_value(metrics[name]), unit, meaning))
    return rows


def signal_units(manifest: Any) -> dict[str, str]:
    """"component.signal" -> unit from a run's manifest.json ({} when it cannot be read).

    Args:
        manifest: the manifest's path (None: no units).
    """
    from cosim.analysis.rundata import read_json_object

    if manifest is None:
        return {}
    try:
        info = read_json_object(manifest).get("signals")
    except Exception:  # the summary is printed whatever the manifest holds
        return {}
    if not isinstance(info, dict):
        return {}
    return {name: str(e.get("unit", "") or "") for name, e in info.items() if isinstance(e, dict)}


def format_value(value: Any) -> str:
    """A metric value for reading: integers as such, floats to 4 significant digits.

    Args:
        value: a number (or anything else, shown as is).
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int) or (value.is_integer() and abs(value) < 1e15):
        return str(int(value))
    return f"{value:.4g}"


def run_rows(result: Any) -> list[tuple[str, str]]:
    """(quantity, value) rows of the run table.

    Args:
        result: a cosim.execution.run.RunResult.
    """
    rows = [("folder", str(result.out_dir)), ("ticks", str(result.ticks)),
            ("sim time", f"{result.sim_time_s:.6g} s"),
            ("wall time", f"{result.wall_time_s:.4g} s"),
            ("real-time factor", f"{result.real_time_factor:.4g}")]
    tick0 = getattr(result, "time_to_tick0_s", None)
    if tick0 is not None:
        rows.append(("time to tick 0", f"{tick0:.3f} s"))
    loop = getattr(result, "loop_time_s", None)
    if loop:       # wall time and real-time factor count tick 0 (start-up); these do not
        rows.append(("loop time (ticks 1..N)", f"{loop:.4g} s"))
        rows.append(("loop real-time factor", f"{result.sim_time_s / loop:.4g}"))
    cpu = getattr(result, "lockstep_cpu", None)
    if cpu is not None:     # the run's processes shared one CPU (cosim.engine.one_cpu)
        rows.append(("lockstep CPU", str(cpu)))
    for key, value in (result.realtime or {}).items():
        rows.append((f"realtime.{key}", f"{value:.4g}" if isinstance(value, float) else str(value)))
    return rows


def print_summary(result: Any, console: Console | None = None) -> None:
    """Print the run table, then the metrics table (when there are metrics).

    Args:
        result: a cosim.execution.run.RunResult.
        console: where to print (default: stdout).
    """
    console = console or Console(highlight=False)
    table = Table(title=f"run {result.status}", show_header=False)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for row in run_rows(result):
        table.add_row(*row)
    console.print(table)
    if not result.metrics:
        return
    metrics = Table(title="metrics")
    metrics.add_column("metric")
    metrics.add_column("value", justify="right")
    metrics.add_column("unit")
    metrics.add_column("meaning")
    for row in metric_rows(result.metrics, signal_units(getattr(result, "manifest", None))):
        metrics.add_row(*row)
    console.print(metrics)
