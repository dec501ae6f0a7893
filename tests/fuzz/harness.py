"""Running one `cosim` command line in this process under a time limit, and what a
clean outcome is (for the fuzz tests)."""

from __future__ import annotations

import re
import signal
from pathlib import Path
from typing import Any

from cosim.cli.app import main

CASE_TIMEOUT_S = 20.0  # far above any case (a few ms to 1 s): only a hang reaches it


class CaseHang(Exception):
    """A case did not end within CASE_TIMEOUT_S."""


def _alarm(signum: int, frame: Any) -> None:
    raise CaseHang(f"no result after {CASE_TIMEOUT_S:g} s")


def run_case(argv: list[str], capsys: Any) -> tuple[int, str]:
    """(exit status, stderr) of `cosim ARGV`, run here; a hang raises CaseHang.

    An exception escaping `main` (a traceback for the user) is re-raised with the
    command line, so the failing case is named.
    """
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_TIMEOUT_S)
    try:
        code = main(argv)
    except CaseHang:
        raise
    except BaseException as exc:
        raise AssertionError(f"cosim {' '.join(argv)} raised {type(exc).__name__}: {exc}") from exc
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    return code, capsys.readouterr().err


_OPTION = re.compile(r"--[a-z]")


def assert_clean_rejection(code: int, err: str, file: Path | None, case: str) -> None:
    """Status 0, 1 or 2 without a traceback; a status 2 names the file (with its line
    when the message is about a place in it) or an option.

    Args:
        code: the exit status.
        err: what the command wrote on stderr.
        file: the scenario file of the case (None: a case about options only).
        case: the case's name for the assertion message.
    """
    assert code in (0, 1, 2), f"{case}: exit status {code}\n{err}"
    assert "Traceback" not in err, f"{case}: traceback\n{err}"
    if code != 2:
        return
    first = err.strip().splitlines()[0] if err.strip() else ""
    assert first.startswith("error: "), f"{case}: no error line\n{err}"
    names_file = file is not None and str(file) in first
    assert names_file or _OPTION.search(first), f"{case}: names no file nor option\n{err}"
