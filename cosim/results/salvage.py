"""Completing a run folder after the master process died, from outside it.

The recorder puts every completed tick into the kernel as the tick completes
(`cosim.results.recorder`: mmap'd spools with a row count), and the manifest
of a running run says what ran. `complete_run_folder`, called by the run's
supervisor (`cosim.execution.supervisor`) once the master is dead, turns the
spools into the CSV files (every complete row, as `cosim recover` does; and
the Parquet files if the run asked for them, or the manifest's "recording"
says why not), and
rewrites the manifest with status "failed", the error and its cause: how the
master ended (signal, exit status, deadline, interrupt), the component and
call under way, the tick and the time.
"""

from __future__ import annotations

import datetime
import json
from pathlib import Path
from typing import Any

from cosim.engine.crumb import CALL_BUILD, CALL_START, CALL_STOP, CALLS
from cosim.errors import ComponentFailure, UserError
from cosim.results.recorder import SIGNALS_FILE, read_signals, write_json
from cosim.results.recover import NoSpoolError, recover


def complete_run_folder(folder: Path | None, verdict: dict[str, Any]) -> str:
    """Rebuild the CSV files and write the failed manifest; the one-line error.

    Args:
        folder: the run folder (its manifest written before tick 0, or before the
            first constructor of a component in the master's process).
        verdict: how the master ended: "kind" ("signal", "exit", "deadline" or
            "interrupted") with "signal", "exit_code", "deadline_s" or "what",
            and "call": (component index in step order, call kind, tick) or None;
            for a constructor (call kind CALL_BUILD), "component": its name.
    Returns:
        the error, naming the component, the tick, the time and the cause.
    """
    if folder is None:
        raise ValueError("no run folder")
    manifest = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    not_rebuilt = None
    try:
        recover(folder, check_live=False)  # the master is dead: no one else records here
    except NoSpoolError:
        pass  # nothing recorded yet, or already converted
    except UserError as exc:  # the spools are kept: said in the error, for cosim recover
        not_rebuilt = f"; the CSV files were not rebuilt: {exc} (spools kept for cosim recover)"
    recovered = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    if "recording" in recovered:  # which files recover wrote (csv, parquet)
        manifest["recording"] = recovered["recording"]
    scenario = manifest.get("scenario", {})
    t0 = float(manifest.get("start_time", scenario.get("start_time") or 0.0))
    tick = float(scenario.get("tick", 0.0))
    last = _last_tick(folder / SIGNALS_FILE, t0, tick)
    cause = _cause(verdict, list(manifest.get("step_order", [])), last, t0, tick)
    message = _message(cause) + (not_rebuilt or "")
    manifest.update({"status": "failed", "error": message, "cause": cause,
                     "ticks": max(last, 0), "sim_time_s": max(last, 0) * tick,
                     "failed_utc": datetime.datetime.now(datetime.timezone.utc)
                     .isoformat(timespec="seconds"),
                     "completed_by": "supervisor"})
    write_json(folder / "manifest.json", manifest)
    if not (folder / "metrics.json").exists():
        write_json(folder / "metrics.json", {})
    return message


def _last_tick(path: Path, t0: float, tick: float) -> int:
    """The last recorded tick (-1: none), from the time of signals.csv's last row, which
    every run records, decimated (`record.every`) or not."""
    try:
        times = read_signals(path)[1][:, 0]
    except (OSError, ValueError, IndexError):
        return -1
    if len(times) == 0:
        return -1
    return round((times[-1] - t0) / tick) if tick > 0 else len(times) - 1


def _cause(verdict: dict[str, Any], order: list[str], last_tick: int, t0: float,
           tick: float) -> dict[str, Any]:
    """The manifest's "cause": the verdict with names and times instead of indexes."""
    cause = {k: v for k, v in verdict.items() if k != "call"}
    call = verdict.get("call")
    if call is not None and call[1] == CALL_BUILD:  # its name came with the verdict
        cause.update(call=CALLS[CALL_BUILD], tick=None, time=t0)
    elif call is not None and call[0] < len(order):
        index, kind, k = call
        cause.update(component=order[index], call=CALLS.get(kind, "call"),
                     tick=None if kind == CALL_START else k, time=t0 + k * tick)
    else:
        last = max(last_tick, 0)
        cause.update(component=None, call=None, tick=last, time=t0 + last * tick)
    return cause


def _message(cause: dict[str, Any]) -> str:
    """One line: what the master was doing and how it ended."""
    kind, call = cause["kind"], cause.get("call")
    if kind == "signal":
        ended = f"the master process was killed by {cause['signal']}"
    elif kind == "exit":
        ended = f"the master process exited with status {cause['exit_code']}"
    elif kind == "deadline":
        ended = (f"no return from its {call} within the deadline of {cause['deadline_s']:g} s "
                 f"(the master process was ended)")
    else:
        ended = f"{cause['what']}"
    if cause["component"] is None:
        return f"{ended} after tick {cause['tick']} (t={cause['time']:.10g} s), outside any component call"
    if kind == "interrupted":
        return (f"{ended}: component {cause['component']!r} did not return from its {call} at "
                f"{_when(cause)} (t={cause['time']:.10g} s); the master process was ended")
    if kind != "deadline":
        ended += f" in its {call}"
    if call == CALLS[CALL_STOP]:
        ended += f" after tick {cause['tick']}"
    return str(ComponentFailure(cause["component"], cause["tick"], cause["time"], ended))


def _when(cause: dict[str, Any]) -> str:
    return "initialization" if cause["tick"] is None else f"tick {cause['tick']}"
