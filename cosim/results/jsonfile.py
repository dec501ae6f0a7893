"""JSON files of a run folder (manifest, metrics), written atomically.

`write_json` writes a temporary file and renames it, so a reader never sees
half a file and a failed write leaves no `.tmp` behind; `write_json_in_place`
falls back to rewriting the existing file when the disk is full. Non-finite
floats become null, so the JSON stays standard.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from pathlib import Path
from typing import Any

from cosim.errors import RunFolderError


def write_json(path: str | Path, data: Any) -> None:
    """Write JSON atomically (temporary file, then rename); non-finite floats become null.

    Args:
        path: destination file.
        data: JSON-serializable data (dicts, lists, str, numbers, bools, None).
    Raises:
        RunFolderError when the file cannot be written.
    """
    write_text_atomically(path, json.dumps(_finite(data), indent=2, sort_keys=False) + "\n")


def write_text_atomically(path: str | Path, text: str) -> None:
    """Write a text file of a run folder through a temporary file and a rename.

    Args:
        path: destination file.
        text: its whole content.
    Raises:
        RunFolderError when it cannot be written; no `.tmp` file is left then.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise RunFolderError(path.parent, exc) from None


def write_json_in_place(path: str | Path, data: Any) -> bool:
    """`write_json`, or, when that fails (a full disk), the existing file rewritten in
    place and compact, reusing its own space; False when neither could be written.

    So a run on a full disk still ends with a manifest that says "failed".

    Args:
        path: destination file.
        data: JSON-serializable data.
    """
    try:
        write_json(path, data)
        return True
    except RunFolderError:
        pass
    try:
        with open(path, "r+", encoding="utf-8") as handle:  # only a file that exists
            handle.truncate(0)
            handle.write(json.dumps(_finite(data), separators=(",", ":")) + "\n")
            handle.flush()
            os.fsync(handle.fileno())
        return True
    except OSError:
        return False


def _finite(data: Any) -> Any:
    """Replace NaN/inf floats by None so the JSON stays standard."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {str(k): _finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_finite(v) for v in data]
    return data
