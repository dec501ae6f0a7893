"""Run metrics: tracking errors, actuator effort, friction estimate, cone hits, vehicle following.

`compute_metrics(run_dir)` reads a run folder and returns the metrics the
paper's experiments are judged by; `write_metrics(run_dir)` merges them into
the folder's `metrics.json` (keeping what components wrote there). A metric
whose signals the run did not record is left out, with a note saying why, and so is
one that is not a finite number (a rate or a square of values near the largest float
overflows) (`analyse_run` returns the notes; `write_metrics` saves them in
`metrics_notes.txt`).

Signals are read by role (cosim.scenario.roles): below, `vehicle.vx` is the vx of
the component that plays the vehicle (`metrics.vehicle`, default the component
named `vehicle`), `controller.*` and `planner.*` likewise. A run where no
component plays a role gets the generic statistics of every signal instead
(cosim.analysis.generic), not these.

A run recorded with `record: {every: N}` gets its metrics.json from every
tick (the recorder's spool, `cosim.execution.finish`); a later analysis of its
folder sees only the recorded rows and says so in its notes.

Definitions (t0 = first tick + `metrics.skip_s` from the scenario, default 0):
- rms_* : time-weighted RMS, sqrt(integral(v^2 dt) / (t_end - t0)), trapezoid rule.
- max_abs_* : max |v| over the ticks from t0.
- yc : the lateral error at the CG as the paper defines it (Fig. 4.7),
  yL - ls psiL: controller.yc, else computed from controller.yL and psiL.
- yc_cg : the CG's geometric offset from the path (signed distance to its
  foot point, left positive): controller.yc_cg. yc is its linear
  approximation; on a curve of curvature rho they differ by about
  ls^2 rho / 2 plus the heading error's share (see controllers/tracking.py).
- max_abs_delta_rate : max |finite difference of controller.delta| over time,
  taken at the controller's period (`components.controller.period`) so a
  held output is not read as a jump within one tick.
- mu_true_final : the last value feeding vehicle.mu (its connected source
  column, else the scenario's vehicle parameter `mu`, else 1.0); only when
  some component plays the vehicle.
- mu_hat_final : the last controller.mu_hat.
- cone_hits : cones touched by the body rectangle (see metrics_cones), when the
  scenario lists cones under `metrics.cones` or
  `components.planner.parameters.cones`.

Vehicle following, when the planner follows a lead (its input planner.lead_x
is connected: the lead is the component feeding it). gap and gap_ref are the
planner's bumper-to-bumper gap along the road and its desired gap
standstill + time_gap * vx, held between planner steps:
- rms_gap_error, max_abs_gap_error : of gap - gap_ref (m), as rms_* / max_abs_*.
- min_time_gap : min gap / vehicle.vx over the ticks with vx >= 1 m/s (s).
- min_ttc : time to collision, min gap / (vehicle.vx - lead.vx) over the ticks
  where the follower is closing in (s); left out if it never closes in.
- gap_overshoot : max(gap_ref - gap, 0): how far the follower came closer than
  the desired gap (m).
- collisions : contacts between the two body rectangles (cosim.analysis.collisions;
  body size as for cone_hits), each run of touching ticks counted once, from
  vehicle.x/y/psi and the lead's x/y/psi at every tick.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosim.analysis.collisions import bodies_overlap, contact_events
from cosim.analysis.cones import cone_hits
from cosim.analysis.generic import STATISTICS, no_roles_note, parse_statistic_name, signal_statistics
from cosim.analysis.stats import drop_non_finite, finite_or_note, rms
from cosim.results.jsonfile import write_text_atomically
from cosim.analysis.rundata import (AnalysisError, RunData, load_run, loaded_run,
                                   read_json_object)

METRIC_NAMES = (
    "rms_yc", "max_abs_yc", "rms_yc_cg", "max_abs_yc_cg", "rms_yL", "max_abs_yL", "rms_psiL", "max_abs_psiL",
    "rms_ex", "max_abs_ex", "max_abs_delta", "max_abs_delta_rate", "max_abs_ay",
    "mu_true_final", "mu_hat_final", "cone_hits",
    "rms_gap_error", "max_abs_gap_error", "min_time_gap", "min_ttc", "gap_overshoot", "collisions",
)
TIME_GAP_MIN_SPEED = 1.0    # m/s: min_time_gap ignores slower ticks (gap / vx grows without bound at rest)
NOTES_FILE = "metrics_notes.txt"


def ordered_metric_names(present: set[str]) -> list[str]:
    """Metric names in table order: the platform's in METRIC_NAMES order, then the generic
    statistics by signal ("min(ball.h)", "max(ball.h)", ..., cosim.analysis.generic), then
    the others (the components' own) sorted.

    Args:
        present: the names some run or sample has.
    """
    generic = {n: parse_statistic_name(n) for n in present}
    statistics = sorted((n for n, p in generic.items() if p is not None),
                        key=lambda n: (generic[n][1], STATISTICS.index(generic[n][0])))
    return ([n for n in METRIC_NAMES if n in present] + statistics
            + sorted(present - set(METRIC_NAMES) - set(statistics)))


def platform_metric(name: str) -> bool:
    """True for a metric this module computes (a vehicle metric or a generic statistic)."""
    return name in METRIC_NAMES or parse_statistic_name(name) is not None


@dataclass
class MetricsReport:
    """Computed metrics and the notes on what was left out and why."""

    values: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def lateral_error_cg(run: RunData) -> np.ndarray | None:
    """yc, the paper's lateral error at the CG: controller.yc, else yL - ls psiL
    with the controller's ls (default 5 m)."""
    yc = run.role_signal("controller", "yc")
    if yc is not None:
        return yc
    y_l, psi_l = run.role_signal("controller", "yL"), run.role_signal("controller", "psiL")
    if y_l is None or psi_l is None:
        return None
    return y_l - run.number(run.role_path("controller", "parameters.ls"), 5.0) * psi_l


def speed_error(run: RunData) -> np.ndarray | None:
    """ex: controller.ex, else vehicle.vx minus controller.vx_ref or planner.v_ref."""
    ex = run.role_signal("controller", "ex")
    if ex is not None:
        return ex
    vx = run.role_signal("vehicle", "vx")
    for role, ref_name in (("controller", "vx_ref"), ("planner", "v_ref")):
        ref = run.role_signal(role, ref_name)
        if vx is not None and ref is not None:
            return vx - ref
    return None


def true_mu(run: RunData) -> tuple[np.ndarray, str]:
    """The friction fed to the vehicle at each tick, and where it came from.

    Follows the connection into `vehicle.mu` (explicit, or the short form
    "a -> vehicle" feeding it from a.mu) to its source column;
    when unconnected, the scenario's `components.vehicle.parameters.mu`, else 1.0.
    """
    src = run.source_of(run.role_column("vehicle", "mu"))
    if src is not None:
        return run.columns[src], src
    where = run.role_path("vehicle", "parameters.mu")
    mu = run.number(where, 1.0)
    source = where if run.lookup(where) is not None else "default 1.0"
    return np.full(len(run.time), mu), source


def _delta_rate(run: RunData, mask: np.ndarray, report: MetricsReport) -> None:
    delta = run.role_signal("controller", "delta")
    if delta is None:
        report.notes.append(f"max_abs_delta_rate: {run.role_column('controller', 'delta')} not recorded")
        return
    period = run.number(run.role_path("controller", "period"), 0.0)
    tick = run.number("tick", 0.0)
    stride = max(1, int(round(period / tick))) if period > 0 and tick > 0 else 1
    t, d = run.time[mask][::stride], delta[mask][::stride]
    if len(t) < 2:
        report.notes.append("max_abs_delta_rate: fewer than two samples")
        return
    if finite_or_note("max_abs_delta_rate", t, d, report.notes):
        report.values["max_abs_delta_rate"] = float(np.max(np.abs(np.diff(d) / np.diff(t))))


def _series_metrics(run: RunData, mask: np.ndarray, report: MetricsReport) -> None:
    ctl, veh = (functools.partial(run.role_column, role) for role in ("controller", "vehicle"))
    # each series read when its turn comes: one column in memory at a time, whatever the run's length
    series = {
        "yc": (lambda: lateral_error_cg(run), f"{ctl('yc')} (or {ctl('yL')}, {ctl('psiL')})"),
        "yc_cg": (lambda: run.role_signal("controller", "yc_cg"), ctl("yc_cg")),
        "yL": (lambda: run.role_signal("controller", "yL"), ctl("yL")),
        "psiL": (lambda: run.role_signal("controller", "psiL"), ctl("psiL")),
        "ex": (lambda: speed_error(run), f"{ctl('ex')} (or {veh('vx')} and a speed reference)"),
        "delta": (lambda: run.role_signal("controller", "delta"), ctl("delta")),
        "ay": (lambda: run.role_signal("vehicle", "ay"), veh("ay")),
    }
    with_rms = {"yc", "yc_cg", "yL", "psiL", "ex"}
    t = run.time[mask]
    for key, (read, source) in series.items():
        names = ([f"rms_{key}"] if key in with_rms else []) + [f"max_abs_{key}"]
        values = read()
        if values is None:
            report.notes.append(f"{', '.join(names)}: {source} not recorded")
            continue
        v = values[mask]
        if not finite_or_note(", ".join(names), t, v, report.notes):
            continue
        if key in with_rms:
            report.values[f"rms_{key}"] = rms(t, v)
        report.values[f"max_abs_{key}"] = float(np.max(np.abs(v)))


def _friction_metrics(run: RunData, report: MetricsReport) -> None:
    if run.roles["vehicle"] is None:
        report.notes.append("mu_true_final: no vehicle (metrics.vehicle, or a component "
                            "named 'vehicle')")
    elif len(run.time):
        report.values["mu_true_final"] = float(true_mu(run)[0][-1])
    mu_hat = run.role_signal("controller", "mu_hat")
    if mu_hat is None:
        report.notes.append(f"mu_hat_final: {run.role_column('controller', 'mu_hat')} not recorded")
    elif len(mu_hat):
        report.values["mu_hat_final"] = float(mu_hat[-1])


def scenario_cones(run: RunData) -> np.ndarray | None:
    """The cone positions (n, 2) the scenario lists, or None when it lists none.

    Raises:
        AnalysisError: the cones field is not a list of [x, y] number pairs.
    """
    for where in ("metrics.cones", run.role_path("planner", "parameters.cones")):
        cones = run.lookup(where)
        if cones is None or (isinstance(cones, list) and not cones):
            continue  # the scenario schema dumps "no cones" as []
        try:
            arr = np.asarray(cones, dtype=float)
        except (TypeError, ValueError):
            arr = np.empty((0, 3))
        if arr.ndim != 2 or arr.shape[1] != 2 or not np.all(np.isfinite(arr)):
            raise AnalysisError(f"{run.run_dir / 'manifest.json'}: scenario.{where}: "
                                f"expected a list of [x, y] number pairs, found {cones!r}")
        return arr
    return None


def run_cone_hits(run: RunData) -> tuple[np.ndarray, np.ndarray] | None:
    """The scenario's cones (n, 2) and, per cone, whether the body touched it.

    The body is `metrics.vehicle_length` x `metrics.vehicle_width` (defaults
    4.5 m x 1.8 m), its front `metrics.vehicle_front` ahead of the CG (default:
    half the length). None when the scenario lists no cones or the run did not
    record the vehicle's x, y and psi.
    """
    cones = scenario_cones(run)
    pose = [run.role_signal("vehicle", s) for s in ("x", "y", "psi")]
    if cones is None or any(p is None for p in pose):
        return None
    front = run.lookup("metrics.vehicle_front")
    hits = cone_hits(*pose, cones,
                     length=run.number("metrics.vehicle_length", 4.5),
                     width=run.number("metrics.vehicle_width", 1.8),
                     front=None if front is None else run.number("metrics.vehicle_front", 0.0))
    return cones, hits


def _cone_metric(run: RunData, report: MetricsReport) -> None:
    found = run_cone_hits(run)
    if found is not None:
        report.values["cone_hits"] = int(np.count_nonzero(found[1]))
    elif scenario_cones(run) is not None:
        pose = ", ".join(run.role_column("vehicle", s) for s in ("x", "y", "psi"))
        report.notes.append(f"cone_hits: {pose} not all recorded")


def lead_component(run: RunData) -> str | None:
    """The component that feeds the planner's lead_x (the lead vehicle), or None without one."""
    source = run.source_of(run.role_column("planner", "lead_x")) if run.roles["planner"] else None
    return None if source is None else source.split(".")[0]


def _collision_metric(run: RunData, lead: str, report: MetricsReport) -> None:
    vehicle = run.roles["vehicle"] or "vehicle"
    poses = [[run.signal(f"{who}.{s}") for s in ("x", "y", "psi")] for who in (vehicle, lead)]
    if any(p is None for pose in poses for p in pose):
        report.notes.append(f"collisions: {vehicle}.x/y/psi or {lead}.x/y/psi not recorded")
        return
    front = run.lookup("metrics.vehicle_front")
    overlap = bodies_overlap(tuple(poses[0]), tuple(poses[1]),
                             length=run.number("metrics.vehicle_length", 4.5),
                             width=run.number("metrics.vehicle_width", 1.8),
                             front=None if front is None else run.number("metrics.vehicle_front", 0.0))
    report.values["collisions"] = contact_events(overlap)


def _following_metrics(run: RunData, mask: np.ndarray, report: MetricsReport) -> None:
    lead = lead_component(run)
    if lead is None:
        return
    _collision_metric(run, lead, report)
    names = (run.role_column("planner", "gap"), run.role_column("planner", "gap_ref"),
             run.role_column("vehicle", "vx"), f"{lead}.vx")
    found = [run.signal(n) for n in names]
    if any(v is None for v in found) or not mask.any():
        report.notes.append(f"gap metrics: {', '.join(names)} not all recorded (or no ticks)")
        return
    gap, gap_ref, vx, v_lead = (v[mask] for v in found)
    t = run.time[mask]
    if not finite_or_note("gap metrics", t, gap - gap_ref + vx + v_lead, report.notes):
        return
    error = gap - gap_ref
    report.values["rms_gap_error"] = rms(t, error)
    report.values["max_abs_gap_error"] = float(np.max(np.abs(error)))
    moving = vx >= TIME_GAP_MIN_SPEED
    if moving.any():
        report.values["min_time_gap"] = float(np.min(gap[moving] / vx[moving]))
    closing = vx > v_lead
    if closing.any():
        report.values["min_ttc"] = float(np.min(np.maximum(gap[closing], 0.0) / (vx - v_lead)[closing]))
    else:
        report.notes.append("min_ttc: the follower never closes in on the lead")
    report.values["gap_overshoot"] = float(max(np.max(-error), 0.0))


def analyse_run(run: RunData, skip_s: float | None = None) -> MetricsReport:
    """Compute every metric the run's signals allow, with notes on the rest.

    Args:
        run: a loaded run folder.
        skip_s: initial transient to exclude (s); None: the scenario's
            `metrics.skip_s`, default 0.
    """
    report = MetricsReport()
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is noted, not warned
        _analyse(run, skip_s, report)
    drop_non_finite(report.values, report.notes)
    return report


def _analyse(run: RunData, skip_s: float | None, report: MetricsReport) -> None:
    if run.every > 1:
        report.notes.append(f"computed from the recorded rows (every {run.every}-th tick, "
                            "record.every), not every tick: metrics.json of the run itself "
                            "was computed from every tick")
    if skip_s is None:
        skip_s = run.number("metrics.skip_s", 0.0)
    if len(run.time) == 0:
        report.notes.append("signals.csv has no rows: no metrics")
        return
    mask = run.time >= run.time[0] + skip_s
    no_ticks = f"skip_s={skip_s} s leaves no ticks: time-series metrics left out"
    if not run.vehicle_run:
        report.notes.append(no_roles_note(run))
        if not mask.any():
            report.notes.append(no_ticks)
            return
        report.values, notes = signal_statistics(run, mask)
        report.notes += notes
        return
    if not mask.any():
        report.notes.append(no_ticks)
    else:
        _series_metrics(run, mask, report)
        _delta_rate(run, mask, report)
    _friction_metrics(run, report)
    _cone_metric(run, report)
    _following_metrics(run, mask, report)


def compute_metrics(run_dir: str | Path, skip_s: float | None = None) -> dict[str, float]:
    """The metrics of one run folder (see the module docstring for definitions).

    Args:
        run_dir: the run folder.
        skip_s: initial transient to exclude (s); None: from the scenario.
    """
    return analyse_run(load_run(run_dir), skip_s).values


def write_metrics(run_dir: str | Path, skip_s: float | None = None,
                  run: RunData | None = None) -> MetricsReport:
    """Compute the metrics and merge them into `run_dir/metrics.json`.

    Keys other components wrote stay; this module's keys are replaced (a metric
    left out now is removed). Notes go to `metrics_notes.txt`.

    Args:
        run_dir: the run folder.
        skip_s: initial transient to exclude (s); None: from the scenario.
        run: `run_dir` already loaded (`load_run`), so a caller that also draws
            the figures parses signals.csv once; None loads it here.
    """
    run_dir = Path(run_dir)
    report = analyse_run(loaded_run(run_dir, run), skip_s)
    path = run_dir / "metrics.json"
    merged = {k: v for k, v in read_json_object(path).items() if not platform_metric(k)}
    merged.update(report.values)
    write_text_atomically(path, json.dumps(merged, indent=2) + "\n")  # no 0-byte file on a full disk
    notes_path = run_dir / NOTES_FILE
    if report.notes:
        write_text_atomically(notes_path, "\n".join(report.notes) + "\n")
    elif notes_path.exists():
        notes_path.unlink()
    return report
