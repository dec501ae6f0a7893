"""Synthetic run folders for the analysis tests (metrics, figures, compare, sweep).

Writes exactly what the recorder's contract says a run folder holds, from
signals given as numpy arrays, so the analysis code can be tested against
analytic values without running a simulation.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def _write_csv(path: Path, header: list[str], rows: np.ndarray) -> None:
    lines = [",".join(header)]
    lines += [",".join(repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")


def write_run(run_dir: Path, time: np.ndarray, columns: dict[str, np.ndarray],
              scenario: dict | None = None, connections: list[str] | None = None,
              arrays: dict[str, tuple[np.ndarray, np.ndarray]] | None = None) -> Path:
    """Write signals.csv, manifest.json and arrays/ into run_dir; return run_dir.

    Args:
        run_dir: folder to create.
        time: tick times.
        columns: "component.signal" -> values (same length as time).
        scenario: the scenario dict stored in the manifest.
        connections: manifest connections ("a.b -> c.d"); None leaves the key out.
        arrays: "component.signal" -> (times, (rows, N) values).
    """
    run_dir.mkdir(parents=True, exist_ok=True)
    names = list(columns)
    rows = np.column_stack([time] + [columns[n] for n in names])
    _write_csv(run_dir / "signals.csv", ["time"] + names, rows)
    manifest = {"scenario": scenario or {"name": run_dir.name}, "ticks": len(time),
                "status": "ok"}
    if connections is not None:
        manifest["connections"] = connections
    (run_dir / "manifest.json").write_text(json.dumps(manifest))
    for name, (times, values) in (arrays or {}).items():
        (run_dir / "arrays").mkdir(exist_ok=True)
        header = ["time"] + [str(i) for i in range(values.shape[1])]
        _write_csv(run_dir / "arrays" / f"{name}.csv", header, np.column_stack([times, values]))
    return run_dir


def lane_change_run(run_dir: Path, offset: float = 0.0, with_alt: bool = True) -> Path:
    """A plausible lane-change run: vehicle, controller and planner signals.

    The vehicle drives at 10 m/s along x and moves 3.5 m left between t=2 and
    t=4 s (a smooth step); `offset` shifts the tracking errors so two runs differ.
    """
    t = np.arange(0, 601) * 0.01
    s = np.clip((t - 2.0) / 2.0, 0.0, 1.0)
    lane_y = 3.5 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    cols = {
        "vehicle.x": 10.0 * t, "vehicle.y": lane_y + offset * np.sin(t),
        "vehicle.psi": 0.05 * np.sin(np.pi * s), "vehicle.vx": 10.0 + 0.1 * np.sin(t),
        "vehicle.ay": 0.5 * np.sin(2 * np.pi * s),
        "controller.yL": 0.1 * np.sin(t) + offset, "controller.psiL": 0.01 * np.cos(t),
        "controller.yc": 0.1 * np.sin(t) + offset - 0.05 * np.cos(t),
        "controller.rho": 0.002 * np.sin(2 * np.pi * s), "controller.ex": 0.1 * np.sin(t),
        "controller.vx_ref": np.full_like(t, 10.0), "controller.delta": 0.02 * np.sin(2 * t),
        "controller.mu_hat": 0.8 + 0.1 * np.exp(-t), "road_friction.value": np.full_like(t, 0.9),
    }
    tw = t[::10]
    px = 10.0 * tw[:, None] + np.arange(64)[None, :] * 0.5
    arrays = {"planner.ref_x": (tw, px), "planner.ref_y": (tw, np.zeros_like(px)),
              "planner.ref_a": (tw, np.full_like(px, 0.2))}
    if with_alt:
        arrays["planner.alt_x"] = (tw, px)
        arrays["planner.alt_y"] = (tw, np.full_like(px, 3.5))
    scenario = {"name": "lane_change", "tick": 0.01,
                "components": {"controller": {"parameters": {"m": 1500.0}}}}
    return write_run(run_dir, t, cols, scenario,
                     connections=["road_friction.value -> vehicle.mu"], arrays=arrays)
