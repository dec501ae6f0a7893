"""A sweep's samples on disk: their outcomes, the samples a sweep lost, its output folder.

Each run task of a sweep (`cosim.execution.sweep`) goes through `recorded_task`, on the
worker: before the run it writes the sample's start mark (`.sample_NNNN.running`, beside
the sample's run folder in OUT/samples: the worker's pid, then, in a worker process of a
cluster the sweep started, Python's fault report if the process dies of a fatal signal,
`faulthandler`), after it the sample's outcome (`.sample_NNNN.outcome.json`: status,
metrics, error) and removes the start mark. So, from the client, whatever became of the
worker:

- an outcome on disk: the sample finished (a task that Dask runs again, its result lost
  with its worker, returns that outcome and does not run the sample twice);
- a start mark and no outcome: the sample's process died while running it (a segfault
  in a component, the kernel's OOM killer); its run folder is completed
  (`complete_sample_folder`: the CSV files from the spools, the manifest "failed" or
  "interrupted" with the error) and the error names what the mark says (the signal,
  the Python line running);
- neither: the sample never started (its task was lost with a worker that died running
  another one), and runs again.

`check_sweep_out` refuses an --out folder that is not empty, unless `force` and the folder
is an earlier sweep's (it holds sweep.json or samples.csv), which `empty_folder` clears.
"""

from __future__ import annotations

import contextlib
import datetime
import faulthandler
import json
import os
import re
import sysconfig
from collections.abc import Callable
from pathlib import Path
from cosim.errors import UserError
from cosim.execution import out_folder

MAX_SAMPLES = 100_000  # a sweep's samples at most: a run folder each (and a row, a task)
SWEEP_INDEX_FILES = ("sweep.json", "samples.csv")  # what makes a folder an earlier sweep's
RUNNING_SUFFIX = ".running"
OUTCOME_SUFFIX = ".outcome.json"
# faulthandler's names of the fatal signals it reports
FAULTS = {"Segmentation fault": "SIGSEGV", "Floating-point exception": "SIGFPE",
          "Floating point exception": "SIGFPE", "Aborted": "SIGABRT", "Bus error": "SIGBUS",
          "Illegal instruction": "SIGILL"}
Outcome = tuple[str, dict[str, float], str]


def check_samples_count(samples: int) -> None:
    """Refuse a --samples outside 1..MAX_SAMPLES (an AnalysisError, a UserError)."""
    from cosim.analysis.rundata import AnalysisError

    if samples < 1:
        raise AnalysisError(f"--samples {samples}: need at least 1")
    if samples > MAX_SAMPLES:
        raise AnalysisError(f"--samples {samples}: at most {MAX_SAMPLES} (a run folder each); "
                            f"split a larger study into sweeps with different --seed or --out")


def check_sweep_out(out: str | Path, force: bool, option: str = "--out") -> bool:
    """Whether the sweep may write into `out`: a missing or empty folder, or with `force` an
    earlier sweep's folder (it holds sweep.json or samples.csv), which must then be emptied.

    Returns:
        True when the folder holds an earlier sweep that `empty_folder` must clear first.
    Raises:
        UserError for an empty name, an occupied folder without `force`, or with it a
        folder that is not a sweep's (`--out / --force` must not empty /).
    """
    folder, in_use = out_folder.occupied(out, option)
    if in_use and not force:
        raise UserError(f"{option} {out}: the folder exists and is not empty (another sweep?); "
                        f"choose another folder, or replace that sweep with --force")
    if in_use and not any((folder / name).is_file() for name in SWEEP_INDEX_FILES):
        raise UserError(f"{option} {out}: the folder is not empty and is not a sweep's folder "
                        f"(no sweep.json or samples.csv); --force replaces only an earlier "
                        f"sweep's folder")
    return in_use


def empty_folder(folder: Path, option: str = "--out") -> None:
    """Remove everything in `folder` (an earlier sweep's, see check_sweep_out)."""
    try:
        out_folder.empty_folder(folder)
    except OSError as exc:
        raise UserError(f"{option} {folder}: cannot replace the earlier sweep there: "
                        f"{exc.strerror or exc}") from None


def marks(run_dir: Path) -> tuple[Path, Path]:
    """The start mark and the outcome file of the sample whose run folder is `run_dir`."""
    run_dir = Path(run_dir)
    return (run_dir.with_name(f".{run_dir.name}{RUNNING_SUFFIX}"),
            run_dir.with_name(f".{run_dir.name}{OUTCOME_SUFFIX}"))


def read_outcome(run_dir: Path) -> Outcome | None:
    """The outcome the sample's task wrote, or None (it did not finish)."""
    try:
        data = json.loads(marks(run_dir)[1].read_text(encoding="utf-8"))
        return str(data["status"]), dict(data["metrics"]), str(data["error"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def recorded_task(task: Callable[..., Outcome], fault_report: bool, index: int,
                  overrides: list[str], run_dir: Path) -> Outcome:
    """Run a sample's task with its start mark and outcome on disk (see the module docstring).

    Args:
        task: (index, overrides, run_dir) -> outcome.
        fault_report: this is a worker process of the sweep's own cluster: Python's fault
            report of a fatal signal goes into the start mark while the sample runs.
    """
    done = read_outcome(run_dir)
    if done is not None:  # ran already: its result was lost with its worker
        return done
    running, outcome_path = marks(run_dir)
    with open(running, "w", encoding="utf-8") as mark:
        mark.write(f"pid {os.getpid()}\n")
        mark.flush()
        if fault_report:
            faulthandler.enable(mark)
        try:
            outcome = task(index, overrides, run_dir)
        except BaseException:
            running.unlink(missing_ok=True)
            raise
        finally:
            if fault_report:
                faulthandler.disable()
    status, metrics, error = outcome
    tmp = outcome_path.with_name(outcome_path.name + ".tmp")
    tmp.write_text(json.dumps({"status": status, "metrics": metrics, "error": error}),
                   encoding="utf-8")
    os.replace(tmp, outcome_path)
    running.unlink(missing_ok=True)
    return outcome


def started(run_dir: Path) -> bool:
    """Whether the sample's task started and did not finish (its start mark is there)."""
    return marks(run_dir)[0].is_file()


def fault_report(run_dir: Path) -> tuple[str | None, str | None]:
    """(the fatal signal, "FILE:LINE in FUNCTION" of the Python code running) from the start
    mark's fault report; None for what it does not say."""
    try:
        text = marks(run_dir)[0].read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None, None
    found = re.search(r"Fatal Python error: ([^\n]+)", text)
    signal_name = None
    if found:
        what = found.group(1).strip()
        signal_name = next((name for fault, name in FAULTS.items() if what.startswith(fault)), what)
    current = text.find("Current thread")
    frames = re.findall(r'File "([^"]+)", line (\d+) in (\S+)', text[current:]) if current >= 0 else []
    # the innermost frame of the user's code, not of the libraries it called (ctypes)
    libraries = {sysconfig.get_paths()[key] for key in ("stdlib", "platstdlib", "purelib", "platlib")}
    own = [f for f in frames if not any(f[0].startswith(lib + os.sep) for lib in libraries)]
    frame = (own or frames or [None])[0]
    where = None if frame is None else f"{Path(frame[0]).name}:{frame[1]} in {frame[2]}"
    return signal_name, where


def died_error(index: int, run_dir: Path) -> str:
    """The one-line error of a sample whose worker process died while running it."""
    signal_name, where = fault_report(run_dir)
    if signal_name is None:
        how = "no fault report: killed, e.g. SIGKILL out of memory, or it exited?"
    else:
        how = f"killed by {signal_name}" + (f" at {where}" if where else "")
    return f"sample {index}: the worker process died while running it ({how})"


def complete_sample_folder(run_dir: Path, status: str, error: str) -> str:
    """Complete the run folder of a sample whose process ended mid-run: the CSV files from
    the spools (`cosim.results.recover`), the manifest with `status` and `error`.

    Returns:
        what to add to the error: " after tick N (t=T s)" from the recovered spools, and
        why the CSV files were not rebuilt if so; "" for no run folder that says "running"
        (nothing to complete).
    """
    from cosim.results.recorder import write_json
    from cosim.results.recover import NoSpoolError, recover

    manifest_path = Path(run_dir) / "manifest.json"
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return ""
    if not isinstance(manifest, dict) or manifest.get("status") != "running":
        return ""
    note = ""
    try:
        recover(run_dir, check_live=False)  # its process is dead: no one records there
    except NoSpoolError:
        pass
    except UserError as exc:
        note = f"; the CSV files were not rebuilt: {exc} (spools kept for cosim recover)"
    with contextlib.suppress(OSError, ValueError):
        recovered = json.loads(manifest_path.read_text(encoding="utf-8"))
        if isinstance(recovered, dict):
            manifest = recovered
    when = ""
    ticks, last = manifest.get("ticks"), manifest.get("last_time_s")
    if manifest.get("status") == "recovered" and isinstance(ticks, int) and last is not None:
        when = f" after tick {ticks} (t={last:.10g} s)"
    manifest.pop("recovered_from_status", None)
    manifest.pop("recovered_utc", None)
    manifest.update({"status": status, "error": error + when + note,
                     "ended_utc": datetime.datetime.now(datetime.timezone.utc)
                     .isoformat(timespec="seconds"),
                     "completed_by": "sweep"})
    with contextlib.suppress(UserError, OSError):
        write_json(manifest_path, manifest)
    return when + note


def lost_outcome(index: int, run_dir: Path, interrupted: bool = False) -> Outcome | None:
    """The outcome of a sample whose task did not come back: its own outcome if it finished,
    failed (its process died) or interrupted if it started; None if it never started.
    The start mark goes once read, the run folder completed."""
    done = read_outcome(run_dir)
    if done is not None:
        return done
    if not started(run_dir):
        return None
    if interrupted and not (run_dir / "manifest.json").exists():
        marks(run_dir)[0].unlink(missing_ok=True)
        return None  # its run had not begun (no manifest): as a sample never started
    ended = _ended_run(run_dir) if interrupted else None
    if ended is not None:  # its run had ended; only its task had not come back
        marks(run_dir)[0].unlink(missing_ok=True)
        return ended
    if interrupted:
        error = f"sample {index}: interrupted (Ctrl-C) while running"
        status = "interrupted"
    else:
        error, status = died_error(index, run_dir), "failed"
    error += complete_sample_folder(run_dir, status, error)
    marks(run_dir)[0].unlink(missing_ok=True)
    return status, {}, error


def _ended_run(run_dir: Path) -> Outcome | None:
    """(status, the metrics it wrote, error) of a run whose final manifest is written;
    None while its manifest says "running" (or cannot be read)."""
    try:
        manifest = json.loads((run_dir / "manifest.json").read_text(encoding="utf-8"))
        metrics = json.loads((run_dir / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict) or manifest.get("status") in (None, "running"):
        return None
    return (str(manifest["status"]), dict(metrics) if isinstance(metrics, dict) else {},
            str(manifest.get("error") or ""))


def remove_marks(run_dirs: list[Path]) -> None:
    """Remove the samples' marks once the sweep has their outcomes."""
    for run_dir in run_dirs:
        for path in marks(run_dir):
            with contextlib.suppress(OSError):
                path.unlink(missing_ok=True)
