"""cosim.quick_exit: a process armed with it skips the teardown, keeps its status and output."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from cosim.resources import CHECKOUT_DIR

SCRIPT = textwrap.dedent("""
    import atexit, sys
    from cosim import quick_exit

    quick_exit.skip_teardown()

    class Held:  # alive until the teardown frees it
        def __del__(self):
            sys.stderr.write("teardown ran\\n")

    held = Held()
    atexit.register(lambda: print("later callback ran"))  # registered after: runs before _end
    print("x" * 100_000)  # more than the pipe's buffer: flushed before os._exit
    sys.stdout.write("no newline at the end")
    sys.exit(quick_exit.exit_status(int(sys.argv[1])))
""")


def run_script(status: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", SCRIPT, status], capture_output=True, text=True,
                          cwd=CHECKOUT_DIR, timeout=60)


def test_status_output_and_callbacks_kept_teardown_skipped():
    done = run_script("3")
    assert done.returncode == 3
    lines = done.stdout.splitlines()
    assert lines[0] == "x" * 100_000
    assert lines[1:] == ["no newline at the endlater callback ran"]
    assert "teardown ran" not in done.stderr


def test_status_zero():
    assert run_script("0").returncode == 0


def test_uncaught_exception_exits_1_with_its_traceback():
    script = ("from cosim import quick_exit\nquick_exit.skip_teardown()\n"
              "raise RuntimeError('boom')\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=CHECKOUT_DIR, timeout=60)
    assert done.returncode == 1
    assert "RuntimeError: boom" in done.stderr


def test_c_stdio_flushed():
    """What native code wrote with printf (an FMU, a shim) reaches a pipe too."""
    script = ("import ctypes, sys\nfrom cosim import quick_exit\nquick_exit.skip_teardown()\n"
              "libc = ctypes.CDLL(None)\nlibc.printf(b'from C\\n')\n"
              "sys.exit(quick_exit.exit_status(0))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=CHECKOUT_DIR, timeout=60)
    assert done.returncode == 0
    assert done.stdout == "from C\n"


def test_cosim_command_status_and_output_kept():
    """The real command arms it: a user error still exits 2 with its one line, and a
    successful command's whole output arrives."""
    bad = subprocess.run([sys.executable, "-m", "cosim.cli.app", "validate", "no_such.yaml"],
                         capture_output=True, text=True, cwd=CHECKOUT_DIR, timeout=120)
    assert bad.returncode == 2
    assert "no_such.yaml" in bad.stderr and "Traceback" not in bad.stderr
    listed = subprocess.run([sys.executable, "-m", "cosim.cli.app", "scenarios"],
                            capture_output=True, text=True, cwd=CHECKOUT_DIR, timeout=120)
    assert listed.returncode == 0
    assert "lane_change" in listed.stdout and "satory_nominal" in listed.stdout


def test_the_cli_registers_no_atexit_callback_before_main_arms_it():
    """`skip_teardown` runs last only if nothing registered before it: importing the CLI
    must not (a callback registered then, such as logging's, would be skipped)."""
    script = "import atexit\nimport cosim.cli.app\nprint(atexit._ncallbacks())\n"
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=CHECKOUT_DIR, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "0"


def test_not_armed_after_an_earlier_callback():
    """A callback registered before (a sitecustomize, a coverage hook) would run after ours,
    that is never: the normal teardown then, and that callback runs."""
    script = ("import atexit, sys\natexit.register(lambda: print('earlier callback ran'))\n"
              "from cosim import quick_exit\nquick_exit.skip_teardown()\n"
              "class Held:\n    def __del__(self):\n        print('teardown ran')\n"
              "held = Held()\nsys.exit(quick_exit.exit_status(4))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=CHECKOUT_DIR, timeout=60)
    assert done.returncode == 4
    assert "earlier callback ran" in done.stdout and "teardown ran" in done.stdout
