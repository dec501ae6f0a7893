"""tests.helpers.lines: a line written together with the one before it is found at once."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from tests.helpers.lines import line_reader, wait_for_line

TWO_LINES_THEN_WAIT = ("import sys, time; sys.stdout.write('listening\\nready\\n'); "
                       "sys.stdout.flush(); time.sleep(30)")


def test_the_second_of_two_lines_written_at_once_is_seen_without_waiting():
    proc = subprocess.Popen([sys.executable, "-c", TWO_LINES_THEN_WAIT], stdout=subprocess.PIPE,
                            text=True)
    try:
        start = time.monotonic()
        wait_for_line(proc, "ready", 20)
        assert time.monotonic() - start < 10  # not found only at a timeout
        assert line_reader(proc).next_line(time.monotonic() + 0.1) is None  # each line once
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def test_a_missing_line_fails_with_what_was_seen_once_the_output_ends():
    proc = subprocess.Popen([sys.executable, "-c", "print('starting'); print('no luck', end='')"],
                            stdout=subprocess.PIPE, text=True)
    try:
        with pytest.raises(AssertionError, match="no line 'ready' .*output: starting\nno luck"):
            wait_for_line(proc, "ready", 20)
    finally:
        proc.wait()
        proc.stdout.close()
