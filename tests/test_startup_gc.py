"""cosim.startup_gc: collection held back while the command (or a component process)
starts, resumed (and the start-up frozen) at tick 0; nothing changes in a process that
only imports the CLI."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from cosim.resources import CHECKOUT_DIR


def run_python(script: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(script), *args],
                          capture_output=True, text=True, cwd=CHECKOUT_DIR, timeout=120)


def test_paused_then_resumed_with_a_freeze():
    done = run_python("""
        import gc
        from cosim import startup_gc
        startup_gc.pause()
        print(gc.isenabled(), startup_gc.paused())
        startup_gc.resume(freeze=True)
        print(gc.isenabled(), gc.get_freeze_count() > 0, startup_gc.paused())
        startup_gc.resume(freeze=True)  # once only
        print(gc.isenabled())
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["False True", "True True False", "True"]


def test_a_hold_beside_the_run_outlasts_a_resume_and_freezes_when_it_lets_go():
    done = run_python("""
        import gc
        from cosim import startup_gc
        startup_gc.pause()                   # a component process while it starts
        print(startup_gc.hold())             # its thread beside the run starts loading
        startup_gc.resume(freeze=True)       # the component is built: the host resumes
        print(gc.isenabled(), gc.get_freeze_count())
        startup_gc.let_go()                  # the load is done
        print(gc.isenabled(), gc.get_freeze_count() > 0)
        print(startup_gc.hold(), gc.isenabled())   # a hold alone, collection on before
        startup_gc.let_go()
        print(gc.isenabled())
        gc.disable()                          # off by another's choice: not this module's to turn on
        print(startup_gc.hold(), gc.isenabled())
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:6] == ["True", "False 0", "True True", "True False", "True",
                                           "False False"]


def test_nothing_paused_outside_the_command():
    done = run_python("""
        import gc, sys
        sys.argv[0] = "pytest"
        import cosim.cli.app
        from cosim import startup_gc
        print(gc.isenabled(), startup_gc.paused())
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "True False"


def test_run_collects_again_from_tick0_and_other_commands_at_once(tmp_path: Path):
    """The real command line: paused from the CLI's import to tick 0 (seen by the tick-0
    hook), collecting and frozen after; `validate` collects as soon as it starts."""
    seen = tmp_path / "seen.json"
    done = run_python("""
        import gc, json, sys
        sys.argv[0] = "/usr/bin/cosim"
        import cosim.cli.app as app
        import cosim.cli.run as run
        seen = {"at import": gc.isenabled()}
        hook = run._tick0_done
        def spy(drawer):
            seen["before tick-0 hook"] = gc.isenabled()
            hook(drawer)
            seen["after tick-0 hook"] = gc.isenabled()
            seen["frozen"] = gc.get_freeze_count() > 0
        run._tick0_done = spy
        seen["status"] = app._command(sys.argv[2:])
        seen["collecting at the end"] = gc.isenabled()
        with open(sys.argv[1], "a") as out:  # the master and its supervisor (forked) each write
            out.write(json.dumps(seen) + "\\n")
    """, str(seen), "run", "lane_change", "--transport", "inproc", "--set", "duration=1",
                      "--no-figures", "--out", str(tmp_path / "run"))
    assert done.returncode == 0, done.stderr
    master, supervisor = sorted((json.loads(line) for line in seen.read_text().splitlines()), key=len,
                                reverse=True)
    assert master == {"at import": False, "before tick-0 hook": False, "after tick-0 hook": True,
                      "frozen": True, "status": 0, "collecting at the end": True}
    assert supervisor == {"at import": False, "status": 0, "collecting at the end": True}
    validated = run_python("""
        import gc, sys
        sys.argv[0] = "/usr/bin/cosim"
        import cosim.cli.app as app
        before = gc.isenabled()
        status = app._command(["validate", "scenarios/lane_change.yaml"])
        print(before, gc.isenabled(), status)
    """)
    assert validated.returncode == 0, validated.stderr
    assert validated.stdout.strip().splitlines()[-1] == "False True 0"


def test_a_child_spawned_from_the_command_script_collects(tmp_path: Path):
    """multiprocessing's spawn (a sweep's Dask workers) re-runs the parent's script as
    `__mp_main__`: the CLI it imports must not pause collection nor take Ctrl-C there."""
    script = tmp_path / "cosim"  # named like the console script
    script.write_text(textwrap.dedent("""
        import gc, multiprocessing, signal, sys
        from cosim.cli.app import main

        def child(out):
            with open(out, "w") as f:
                f.write(f"{gc.isenabled()} {signal.getsignal(signal.SIGINT) is signal.default_int_handler}")

        if __name__ == "__main__":
            print(gc.isenabled(), flush=True)  # the command itself: paused
            process = multiprocessing.get_context("spawn").Process(target=child, args=(sys.argv[1],))
            process.start()
            process.join()
            sys.exit(process.exitcode)
    """))
    out = tmp_path / "child.txt"
    # SIGINT as a terminal leaves it: a suite started in the background (`cmd &`) inherits it
    # ignored, and Python installs its handler only over the default action
    done = subprocess.run([sys.executable, str(script), str(out)], capture_output=True, text=True,
                          cwd=CHECKOUT_DIR, timeout=120,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"
    assert out.read_text() == "True True"


def test_a_large_start_up_is_collected_before_the_freeze():
    """Above COLLECT_FIRST_ABOVE objects made since the pause, garbage is collected before the
    freeze (numba compiling afresh leaves ~200,000 unreachable objects); below, it is frozen."""
    done = run_python("""
        import gc
        from cosim import startup_gc

        def cycles(n):
            for _ in range(n):
                a = []
                a.append(a)  # unreachable once the loop moves on, but only a collection frees it

        startup_gc.pause()
        cycles(startup_gc.COLLECT_FIRST_ABOVE + 50_000)
        startup_gc.resume(freeze=True)
        large = gc.get_freeze_count()
        gc.unfreeze()
        gc.collect()
        startup_gc.pause()
        cycles(20_000)
        startup_gc.resume(freeze=True)
        small = gc.get_freeze_count()
        print(large, small)
    """)
    assert done.returncode == 0, done.stderr
    large, small = map(int, done.stdout.split())
    assert large < 100_000        # the 350,000 cycles were collected first
    assert small >= 20_000        # a small start-up is frozen as it is, its garbage too
