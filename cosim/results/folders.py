"""Default output folders: a fresh `<parent>/<name>-<UTC timestamp>` that does not exist yet."""

from __future__ import annotations

import datetime
from pathlib import Path


def stamped_folder(parent: str | Path, name: str,
                   now: datetime.datetime | None = None) -> Path:
    """A fresh folder parent/<name>-<UTC timestamp> (a suffix -2, -3... when it exists).

    Args:
        parent: the folder to create it in (e.g. "runs", "comparisons").
        name: the leading part of the folder's name.
        now: the time to stamp (default: now, UTC).
    """
    now = now or datetime.datetime.now(datetime.timezone.utc)
    base = Path(parent) / f"{name}-{now.strftime('%Y%m%dT%H%M%SZ')}"
    candidate, n = base, 1
    while candidate.exists():
        n += 1
        candidate = base.with_name(f"{base.name}-{n}")
    return candidate
