"""Where the analysis commands (plot, compare, sweep, export-ssp) write: folders made as
needed, as `cosim run --out` makes its run folder, and a path that cannot be written
refused with one line naming it (a `UserError`), not an OSError's traceback.
"""

from __future__ import annotations

from pathlib import Path

from cosim.errors import UserError


def _file_in_the_way(folder: Path) -> Path | None:
    """The first of `folder`'s ancestors (or itself), from the root down, that exists and is
    not a folder; None when there is none."""
    for candidate in (*reversed(folder.parents), folder):
        if not candidate.exists():
            return None
        if not candidate.is_dir():
            return candidate
    return None


def check_folder(folder: str | Path, label: str | None = None) -> Path:
    """Refuse, before anything is made, a folder to write in that cannot be one.

    Args:
        folder: the folder (it need not exist).
        label: what a message starts with, e.g. "--out sweeps/x" (default: the folder).
    Raises:
        UserError: a file stands where the folder or one of its parents must be.
    """
    folder = Path(folder)
    in_the_way = _file_in_the_way(folder)
    if in_the_way is not None:
        which = "" if in_the_way == folder else f"{in_the_way} "
        raise UserError(f"{label or folder}: {which}is a file, not a folder")
    return folder


def make_folder(folder: str | Path, label: str | None = None) -> Path:
    """Create a folder and its missing parents (an existing one is fine).

    Args:
        folder: the folder.
        label: what a message starts with, e.g. "--out sweeps/x" (default: the folder).
    Raises:
        UserError: a file stands where a folder is needed, or the folder cannot be made
            (no permission, read-only file system).
    """
    folder = check_folder(folder, label)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{label or folder}: cannot create the folder {folder}: "
                        f"{exc.strerror or exc}") from None
    return folder


def check_output_file(path: str | Path, label: str | None = None) -> Path:
    """Refuse, before anything is made, a file to write that is a folder or lies under a file.

    Args:
        path: the file to write (its folder need not exist).
        label: what a message starts with, e.g. "--out x.png" (default: the path).
    Raises:
        UserError: as the message says.
    """
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{label or path}: is a folder; give the name of the file to write")
    in_the_way = _file_in_the_way(path.parent)
    if in_the_way is not None:
        raise UserError(f"{label or path}: {in_the_way} is a file, not a folder")
    return path


def output_file(path: str | Path, label: str | None = None) -> Path:
    """Make the folder a file is to be written in (see check_output_file, make_folder).

    Args:
        path: the file to write.
        label: what a message starts with, e.g. "--out x.png" (default: the path).
    Raises:
        UserError: the path is a folder, or its folder cannot be made.
    """
    path = check_output_file(path, label)
    make_folder(path.parent, label or str(path))
    return path


def write_failure(path: str | Path, exc: OSError) -> UserError:
    """The error to raise when writing `path` failed with `exc` (no permission, disk full)."""
    return UserError(f"{path}: cannot write: {exc.strerror or exc}")
