"""`cosim recover`: rebuild a run folder from its recording spools.

A run whose master was killed, or whose folder could not be written (a full
disk), keeps the binary spools of the recorder (`cosim.results.recorder`).
`recover` turns every spool into its CSV (and its Parquet file when the run
asked for one: `record.format`; decimated as the run asked, `record.every`)
and rewrites the manifest: status
"recovered", the ticks on disk and the time of the last one, so that the
folder no longer claims to be "running".

A run that is still recording holds the recording lock of its signals spool
(`cosim.results.recorder.hold_recording_lock`): `recover` refuses its folder,
as rebuilding and removing a live spool would end the run and cut its CSV short.
A rebuild that reads fewer rows than a spool's count is an error that keeps
every spool.
"""

from __future__ import annotations

import datetime
import json
import struct
from pathlib import Path

from cosim.errors import UserError
from cosim.results.csv_writer import (HEADER_SUFFIX, SPOOL_SUFFIX, SpoolError, SpoolHeader,
                                      read_header, rebuild_csv)
from cosim.results.parquet import pyarrow_missing, write_parquet
from cosim.results.recorder import (ARRAYS_DIR, SIGNALS_FILE, RunFolderError, is_being_recorded,
                                    write_json)

MANIFEST_FILE = "manifest.json"


class NoSpoolError(UserError):
    """The run folder holds no spool: nothing was recorded, or it was already converted."""


def recover(run_dir: str | Path, keep_spool: bool = False,
            check_live: bool = True) -> list[tuple[Path, int, int]]:
    """Rebuild a run folder's CSV files from its spools and mark its manifest recovered.

    Args:
        run_dir: the run folder.
        keep_spool: keep the spools after the CSV files are written.
        check_live: refuse a folder whose run is still recording (False: the caller
            saw the master die, e.g. its supervisor).
    Returns:
        (CSV path, rows written, bytes of a partial last row ignored) per table, then
        (Parquet path, rows, 0) per table when the run asked for Parquet.
    Raises:
        UserError when the folder holds no spool, a spool cannot be read, its run is
        still recording, or the folder cannot be written (RunFolderError: free space,
        then recover again).
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise UserError(f"{run_dir}: not a folder")
    paths = sorted(run_dir.glob(f"*{HEADER_SUFFIX}")) + sorted(
        (run_dir / ARRAYS_DIR).glob(f"*{HEADER_SUFFIX}"))
    if not paths:
        raise NoSpoolError(f"{run_dir}: no recording spool (*{SPOOL_SUFFIX} with its "
                        f"*{HEADER_SUFFIX} header) to recover from")
    try:
        headers = [read_header(p) for p in paths]
        if check_live:
            _refuse_live(run_dir, headers)
        done = [(h.csv_path, *rebuild_csv(h)) for h in headers]
        parquet, not_written = _write_parquet(headers, [rows for _, rows, _ in done])
        signals = next((h for h in headers if h.csv == SIGNALS_FILE), None)
        if signals is not None:
            _mark_recovered(run_dir / MANIFEST_FILE, signals, bool(parquet), not_written)
        done += parquet
    except SpoolError as exc:
        raise UserError(str(exc)) from None
    except OSError as exc:
        raise RunFolderError(run_dir, f"{exc.strerror or exc} (free space or fix the "
                                      "permissions, then run cosim recover again)") from None
    if not keep_spool:
        for header in headers:
            header.spool_path.unlink(missing_ok=True)
            header.path.unlink(missing_ok=True)
    return done


def _refuse_live(run_dir: Path, headers: list[SpoolHeader]) -> None:
    """A UserError when a live recorder holds the lock of one of the spools."""
    for header in headers:
        if is_being_recorded(header.spool_path):
            pid = "" if header.pid is None else f" (pid {header.pid})"
            raise UserError(f"run folder {run_dir} is still being written by a running "
                            f"run{pid}; recover it after it ends")


def _write_parquet(headers: list[SpoolHeader], rows: list[int]
                   ) -> tuple[list[tuple[Path, int, int]], str | None]:
    """The Parquet files of the tables that asked for them, and why they were not
    written (pyarrow missing here), or None."""
    wanted = [(h, n) for h, n in zip(headers, rows) if "parquet" in h.formats]
    missing = pyarrow_missing() if wanted else None
    if missing is not None:
        return [], f"parquet: {missing}; only the CSV files were rebuilt"
    return [(write_parquet(h), n, 0) for h, n in wanted], None


def _mark_recovered(manifest_path: Path, signals: SpoolHeader, parquet: bool,
                    not_written: str | None) -> None:
    """Rewrite the manifest (when there is one) with status "recovered", the ticks on
    disk and the last tick's time, read from the signals spool; its "recording" says
    which files were rebuilt ("formats_written") and why not the others."""
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return  # no readable manifest: the CSV files are what there is to recover
    if not isinstance(manifest, dict):
        return
    rows, last_time = _last_row_time(signals)
    previous = manifest.get("status")
    manifest.update({
        "status": "recovered",
        "recovered_from_status": previous,
        "error": manifest.get("error") or f"the run ended without finishing (status {previous!r})",
        "ticks": max(rows - 1, 0),
        "last_time_s": last_time,
        "sim_time_s": None if last_time is None else last_time - _start_time(manifest),
        "recovered_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec="seconds"),
    })
    recording = manifest.get("recording")
    recording = dict(recording) if isinstance(recording, dict) else {}
    recording["formats_written"] = ["csv", "parquet"] if parquet else ["csv"]
    if not_written is not None:
        recording["not_written"] = not_written
    manifest["recording"] = recording
    write_json(manifest_path, manifest)


def _start_time(manifest: dict) -> float:
    """The run's start time: the master's (manifest), else the scenario's, else 0."""
    for value in (manifest.get("start_time"), manifest.get("scenario", {}).get("start_time")):
        if isinstance(value, (int, float)):
            return float(value)
    return 0.0


def _last_row_time(header: SpoolHeader) -> tuple[int, float | None]:
    """(complete rows in the spool, time of the last one or None)."""
    size = header.row_bytes
    with open(header.spool_path, "rb") as spool:
        rows = header.committed_bytes(spool.fileno()) // size
        if rows == 0:
            return 0, None
        spool.seek(header.data_offset + (rows - 1) * size)
        raw = spool.read(8)
    order = "<" if header.byteorder == "little" else ">"
    return rows, struct.unpack(f"{order}d", raw)[0]
