"""CLI conventions: -h everywhere, --version, shell completion, examples quoted so they paste."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys

import pytest

import cosim
from cosim.cli.app import app, main
from tests.helpers.paths import REPO_ROOT

COMMANDS = ["run", "validate", "schema", "scenarios", "build-fmus", "plot", "compare", "sweep",
            "recover", "watch", "worker", "workers", "router"]
SHELL_SPECIAL = re.compile(r"[\[\]{}*?()<>|;&$]")


@pytest.mark.parametrize("command", [[], *([c] for c in COMMANDS)])
def test_dash_h_is_help(command, capsys):
    assert main([*command, "-h"]) == 0
    assert "Usage: cosim" in capsys.readouterr().out


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"cosim {cosim.__version__}"


def test_shell_completion_script():
    # A process of its own, with the shell named on the command line: typer otherwise
    # guesses the shell from the parent process (here pytest, not a shell).
    env = {**os.environ, "SHELL": "/bin/bash", "_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION": "1"}
    done = subprocess.run([sys.executable, "-m", "cosim.cli.app", "--show-completion", "bash"],
                          capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 0, done.stderr
    assert "complete" in done.stdout and "cosim" in done.stdout


DOCS = [REPO_ROOT / "README.md", REPO_ROOT / "scenarios" / "README.md",
        *sorted((REPO_ROOT / "docs").glob("*.md"))]
BARE_OVERRIDE = re.compile(r"^[a-z_]+(\.[A-Za-z_0-9]+)+=.*[\[\]{}*?]")


def _doc_spans() -> list[tuple[str, str]]:
    """(file, text) of every `code span` and indented or fenced command line in the docs."""
    found = []
    for path in DOCS:
        for line in path.read_text(encoding="utf-8").splitlines():
            spans = re.findall(r"`([^`]+)`", line)
            if line.strip().startswith("cosim "):
                spans.append(line.strip())
            found += [(path.name, span) for span in spans]
    return found


def test_doc_examples_are_quoted_so_they_paste():
    spans = _doc_spans()
    commands = [(f, s) for f, s in spans if s.startswith(("cosim ", "--set", "--vary"))]
    assert len(commands) > 20
    unquoted = [(f, s) for f, s in commands if any(SHELL_SPECIAL.search(v) for v in _set_values(s))]
    assert unquoted == []
    bare = [(f, s) for f, s in spans if BARE_OVERRIDE.match(s)]  # an override shown without --set '...'
    assert bare == []


def _set_values(command: str) -> list[str]:
    """The values given to --set / --vary / --signals that are not quoted."""
    values = []
    for match in re.finditer(r"--(?:set|vary|signals)[ =](\S+)", command):
        value = match.group(1)
        if not value.startswith(("'", '"')):
            values.append(value)
    return values


def test_help_examples_parse_as_shell_words():
    for command in app.registered_commands:
        doc = command.callback.__doc__ or ""
        for line in doc.splitlines():
            if line.strip().startswith("cosim ") or "Example: cosim " in line:
                text = line.strip().split("Example: ", 1)[-1]
                assert _set_values(text) == [] or not any(
                    SHELL_SPECIAL.search(v) for v in _set_values(text)), text
                shlex.split(text)  # balanced quotes
