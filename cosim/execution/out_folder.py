"""The folder a command writes its results into (`cosim run --out`, `cosim sweep --out`).

Both refuse an empty name and a folder they cannot read, tell whether the folder already
holds something (which they refuse unless `--force`, each by its own rule of what it may
replace), and empty one they replace.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from cosim.errors import UserError


def occupied(out: str | Path, option: str) -> tuple[Path, bool]:
    """The folder `out` names, and whether it exists with something in it.

    Args:
        out: the folder asked for.
        option: how the user named it, for the messages ("--out", "out").
    Raises:
        UserError for an empty name or a folder that cannot be read.
    """
    if not str(out).strip():
        raise UserError(f"{option} needs a folder name, got an empty one")
    folder = Path(out)
    try:
        return folder, folder.is_dir() and any(folder.iterdir())
    except OSError as exc:
        raise UserError(f"{option} {out}: cannot read the folder: {exc.strerror or exc}") from None


def empty_folder(folder: Path) -> None:
    """Remove what `folder` holds (its symbolic links, not what they point to); OSError
    when something cannot be removed."""
    for entry in folder.iterdir():
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()
