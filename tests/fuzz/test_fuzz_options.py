"""Fuzz of the command-line options: bad endpoints, bad numbers, missing files and
unwritable paths, alone and combined, through `cosim.cli.app.main` in this process.

Each case must end within its time limit, without a traceback, and a rejection
must be one "error:" line with status 2 that names the option or the file.
Only commands that start no process are fuzzed here (a valid `--transport
inproc` run is allowed to go ahead: the scenario is a few ticks long).
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from tests.fuzz.harness import assert_clean_rejection, run_case
from tests.helpers.components import GOOD

BAD_ENDPOINTS = ["bogus", "udp//x", "tcp/1.2.3.4:99999", "tcp/:7447", "tcp/host:", "",
                 "tcp/127.0.0.1:x", "/x", "tcp", "TCP/127.0.0.1:1"]
BAD_NUMBERS = ["abc", "", "-1", "0", "nan", "inf", "-inf", "1e999", "1e-9", "0x10", "1,5"]


def _paths(tmp_path: Path) -> dict[str, Path]:
    """Files and folders the cases point at: a scenario, missing, unwritable, odd ones."""
    good = tmp_path / "good.yaml"
    good.write_text(GOOD)
    full = tmp_path / "occupied"
    full.mkdir(exist_ok=True)
    (full / "old.txt").write_text("a previous run")
    empty = tmp_path / "empty_dir"
    empty.mkdir(exist_ok=True)
    return {"good": good, "missing": tmp_path / "missing.yaml", "dir": empty,
            "occupied": full, "proc": Path("/proc/x/run"), "zero": Path("/dev/zero"),
            "file": good}


def generate_option_cases(seed: int, count: int, paths: dict[str, Path]) -> list[list[str]]:
    """`count` command lines, reproducible from `seed`."""
    rng = random.Random(seed)
    good, out = str(paths["good"]), str(paths["dir"].parent / "out")
    makers = [
        lambda: ["run", good, "--transport", "inproc", "--out", out + str(rng.random()),
                 "--no-figures", rng.choice(["--realtime", "--deadline", "--max-ticks"]),
                 rng.choice(BAD_NUMBERS)],
        lambda: ["run", good, "--transport", "inproc", "--no-figures", "--out",
                 str(rng.choice([paths["occupied"], paths["proc"], paths["file"]]))],
        lambda: ["run", good, "--out", "", "--transport", "inproc"],
        lambda: ["run", good, rng.choice(["--connect", "--listen"]), rng.choice(BAD_ENDPOINTS)],
        lambda: ["run", good, "--transport", rng.choice(["bogus", "", "INPROC"])],
        lambda: ["run", good, "--transport", "inproc", "--place", rng.choice(["x", "=", "gain="])],
        lambda: ["run", good, "--transport", "inproc", "--deploy",
                 str(rng.choice([paths["missing"], paths["zero"], paths["dir"]]))],
        lambda: ["run", str(rng.choice([paths["missing"], paths["zero"], paths["dir"]])),
                 "--transport", "inproc"],
        lambda: ["validate", good, "--set", rng.choice(["x", "=1", "tick=[", "name=../x",
                                                         "duration=1e12", "tick=true"])],
        lambda: ["validate", good, "--max-ticks", rng.choice(BAD_NUMBERS)],
        lambda: ["watch", rng.choice(["abc", "*", "a/b"]), "--connect", rng.choice(BAD_ENDPOINTS)],
        lambda: ["watch", "abc", "--connect", "tcp/127.0.0.1:1", "--every",
                 rng.choice(["0", "-3", "abc"])],
        lambda: ["build-fmus", "--out", str(rng.choice([paths["proc"], paths["zero"]]))],
        lambda: ["recover", str(rng.choice([paths["missing"], paths["dir"], paths["file"]]))],
        lambda: ["sweep", good, "--vary", rng.choice(["a=3:1", "x", "a=b:c", "duration=1:2"]),
                 "--samples", rng.choice(["0", "-1", "abc", "2"]), "--out", out + "_sweep"],
        lambda: ["plot", str(rng.choice([paths["missing"], paths["dir"]]))],
        lambda: [rng.choice(["run", "validate", "watch", "recover"]), "--no-such-option"],
        lambda: ["no-such-command"],
    ]
    return [rng.choice(makers)() for _ in range(count)]


def _subject(argv: list[str], paths: dict[str, Path]) -> Path | None:
    """The path a case is about (its rejection names it): an odd one, else the scenario."""
    given = [Path(arg) for arg in argv if arg and any(arg == str(p) for p in paths.values())]
    odd = [path for path in given if path != paths["good"]]
    return odd[-1] if odd else (given[0] if given else None)


def _check(tmp_path: Path, capsys, cases: list[list[str]], paths: dict[str, Path]) -> dict:
    codes: dict[int, int] = {}
    for i, argv in enumerate(cases):
        code, err = run_case(argv, capsys)
        assert_clean_rejection(code, err, _subject(argv, paths), f"case {i}: cosim {argv}")
        codes[code] = codes.get(code, 0) + 1
    return codes


def test_option_errors_are_one_line_with_status_2(tmp_path, capsys):
    paths = _paths(tmp_path)
    codes = _check(tmp_path, capsys, generate_option_cases(5, 160, paths), paths)
    assert codes.get(2, 0) > 100


@pytest.mark.slow
@pytest.mark.parametrize("seed", [17, 29])
def test_many_more_option_cases(tmp_path, capsys, seed):
    paths = _paths(tmp_path)
    _check(tmp_path, capsys, generate_option_cases(seed, 600, paths), paths)
