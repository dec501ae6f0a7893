"""run.mcap from a run folder: the recorded signals with Foxglove's well-known schemas.

`write_run_mcap(run_dir)` reads what the recorder wrote (signals.csv, whose
floats are the spooled float64 values exactly, arrays/*.csv and
manifest.json) and writes run.mcap beside them with the channels of
`cosim.foxglove.channels`: /tf poses, /scene/road, /scene/body, one
/scene/<window> per planned trajectory and /signals/<component> for every
scalar. It runs after the lockstep has ended (`record: {mcap: true}` or
`cosim run --mcap`), so it costs the run nothing and also converts older or
recovered runs (`cosim mcap RUN_DIR`). A road that cannot be rebuilt leaves
/scene/road empty and is reported, the rest is written.
"""

from __future__ import annotations

from pathlib import Path

import foxglove

from controllers.spec import SpecError
from cosim.analysis.road import lane_lines, scenario_road
from cosim.analysis.rundata import RunData, load_run
from cosim.foxglove.channels import Layout, RunChannels, nanoseconds

MCAP_FILE = "run.mcap"


def _body(run: RunData) -> tuple[float, float, float]:
    """Vehicle length, width and CG-to-front distance (the metrics' body)."""
    length = run.number("metrics.vehicle_length", 4.5)
    front = run.lookup("metrics.vehicle_front")
    return (length, run.number("metrics.vehicle_width", 1.8),
            0.5 * length if front is None else run.number("metrics.vehicle_front", 0.0))


def _array_names(run: RunData) -> list[str]:
    folder = run.run_dir / "arrays"
    return sorted(p.name[:-len(".csv")] for p in folder.glob("*.csv")) if folder.is_dir() else []


def write_run_mcap(run_dir: str | Path, run: RunData | None = None) -> tuple[Path, list[str]]:
    """Write <run_dir>/run.mcap; returns its path and notes (what could not be drawn).

    Args:
        run_dir: a run folder with signals.csv.
        run: the folder already loaded, if it is.
    """
    run = run or load_run(run_dir)
    scalars = [n for n in run.columns]
    layout = Layout.of(scalars, _array_names(run))
    out = Path(run_dir) / MCAP_FILE
    notes: list[str] = []
    context = foxglove.Context()
    writer = foxglove.open_mcap(out, allow_overwrite=True, context=context)
    try:
        channels = RunChannels(context, layout)
        try:
            found = scenario_road(run)
            lines = lane_lines(found) if found is not None else []
        except SpecError as exc:
            lines = []
            notes.append(f"road not in {MCAP_FILE}: {exc}")
        channels.log_static(lines, _body(run), nanoseconds(float(run.time[0])) if run.time.size else 0)
        _log_ticks(run, layout, channels)
        _log_windows(run, layout, channels)
    finally:
        writer.close()
    return out, notes


def _log_ticks(run: RunData, layout: Layout, channels: RunChannels) -> None:
    columns = [run.columns[n].tolist() for n in layout.scalars]
    for k, t in enumerate(run.time.tolist()):
        channels.log_tick(t, [c[k] for c in columns])


def _log_windows(run: RunData, layout: Layout, channels: RunChannels) -> None:
    for k, (_, x_name, y_name) in enumerate(layout.windows):
        xs, ys = run.array(x_name), run.array(y_name)
        if xs is None or ys is None:
            continue
        for t, x, y in zip(xs.times.tolist(), xs.values.tolist(), ys.values.tolist()):
            channels.log_window(k, t, x, y)
