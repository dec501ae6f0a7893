"""Component OS processes: spawn the runner, describe how one ended, reap them all.

Each process runs `python -m cosim.transport.zenoh.runner --name <name> --spec-stdin`,
so `ps` shows which component it hosts, and nothing more: the run id, endpoint,
credential, class and parameters come as one JSON line on its stdin. Its stdout and stderr go to a
temporary file whose tail is quoted when the process dies unexpectedly.
This module loads neither numpy nor zenoh: the master spawns the processes
before it loads them, so that they start in parallel with its own imports.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cosim
from cosim.errors import UserError
from cosim.scenario.imports import pythonpath
from cosim.transport.launch import PythonComponentLaunch
from cosim.transport.zenoh import runtime
from cosim.transport.zenoh.auth import Credential

TAIL_CHARS = 800
STOPPED = "process stopped or not responding (it is stopped: SIGSTOP or a debugger)"
PIPE_SAFE_BYTES = 16384  # written at once into an empty pipe (Linux pipes hold 64 KiB)


def _json_default(value: Any) -> Any:
    import numpy as np  # only numpy values reach here, so numpy is loaded already

    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON-serializable")


def _child_env(run_id: str, import_path: Sequence[str] = (),
               one_runtime_thread: bool = True) -> dict[str, str]:
    """Environment letting the child import cosim and the scenario's modules: `import_path`
    (the scenario's folder and the cwd, `cosim.scenario.imports`), else the cwd;
    COSIM_RUN_ID names its run for its owner (/proc/PID/environ is owner-only).

    OpenBLAS gets one thread unless the user says otherwise: a component works
    on small vectors, and numpy's import then starts no thread pool (about a
    third faster on a busy 2-core machine, and no oversubscription). Zenoh's
    runtime likewise (`runtime`: one message in flight needs no pools), unless
    `one_runtime_thread` is False (a run with workers keeps Zenoh's pools).
    """
    env = runtime.child_environment(dict(os.environ)) if one_runtime_thread else dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    roots = [*(import_path or [os.getcwd()]), str(Path(cosim.__file__).resolve().parent.parent)]
    env["PYTHONPATH"] = pythonpath(roots, env.get("PYTHONPATH"))
    env["COSIM_RUN_ID"] = run_id
    return env


def _runner_argv(name: str) -> list[str]:
    return [sys.executable, "-m", "cosim.transport.zenoh.runner", "--name", name, "--spec-stdin"]


def _params_json(spec: PythonComponentLaunch) -> str:
    """The constructor parameters as JSON; UserError naming the component if they are not."""
    try:
        return json.dumps(dict(spec.parameters), default=_json_default)
    except (TypeError, ValueError) as exc:
        raise UserError(f"component {spec.name!r}: parameters cannot be sent to its "
                        f"process: {exc}") from None


class ChildProcess:
    """One component process. Everything but its name reaches it on its stdin (one
    JSON line): run id, endpoint, the run's credential, class and parameters, so
    nothing of the run shows on a command line.

    Args:
        spec: what the process hosts.
        run_id: the run's id (scopes every key).
        endpoint: the master's listen endpoint the child connects to.
        credential: the run's `auth.Credential` (None: a plain session).
        session_config: a full Zenoh config document replacing the default peer
            config (a worker's TLS, ACL and credential), or None.
        handshake_timeout_s: the process ends by itself when no master has asked
            for its handshake by then (None: the runner's default).
    """

    is_local = True  # a process of this machine (a worker's stand-in says False)
    verdict_wait_s = 0.2  # after its token vanished, how long its exit code may take to show

    def __init__(self, spec: PythonComponentLaunch, run_id: str, endpoint: str, *,
                 credential: Credential | None = None,
                 session_config: dict[str, Any] | None = None,
                 handshake_timeout_s: float | None = None,
                 one_runtime_thread: bool = True) -> None:
        self._session = {"run_id": run_id, "connect": endpoint,
                         "auth": credential.to_json() if credential else None,
                         "zenoh_config": session_config,
                         "handshake_timeout_s": handshake_timeout_s}
        self._start(spec.name, run_id, _runner_argv(spec.name), spec.import_path,
                    one_runtime_thread)
        self.send_spec(spec)

    @classmethod
    def prestart(cls, name: str, run_id: str, endpoint: str, preload: str | None = None,
                 import_path: Sequence[str] = (),
                 credential: Credential | None = None) -> "ChildProcess":
        """Start the process of component `name` before its class, parameters and
        period are known: it loads its modules (numpy, zenoh, `preload`), then
        waits for `send_spec` on its stdin (and exits quietly if stdin closes first).

        Args:
            name: the component's name (on the command line, for ps).
            run_id: the run's id.
            endpoint: the master's listen endpoint the child will connect to.
            preload: a module the component's class probably lives in, or None.
            import_path: folders in front of its import path (the scenario's, the cwd).
            credential: the run's credential (None: a plain session).
        """
        child = cls.__new__(cls)
        child._session = {"run_id": run_id, "connect": endpoint,
                          "auth": credential.to_json() if credential else None}
        child._start(name, run_id,
                     [*_runner_argv(name), *(["--preload", preload] if preload else [])],
                     import_path)
        return child

    def send_spec(self, spec: PythonComponentLaunch) -> None:
        """Give the process its class, parameters and period (and its session).

        Args:
            spec: the launch description; its name must be this process's.
        """
        if spec.name != self.name:
            raise ValueError(f"spec of {spec.name!r} sent to the process of {self.name!r}")
        line = json.dumps({"class_path": spec.class_path, "period_ticks": spec.period_ticks,
                           "steps": spec.steps,
                           "parameters": json.loads(_params_json(spec)),
                           **self._session}).encode() + b"\n"
        if len(line) <= PIPE_SAFE_BYTES:
            self._write_spec(line)
        else:  # the child reads only once its imports are done: do not block the master
            threading.Thread(target=self._write_spec, args=(line,), daemon=True).start()

    def _write_spec(self, line: bytes) -> None:
        try:
            self.popen.stdin.write(line)
            self.popen.stdin.close()
        except (OSError, ValueError):
            pass  # the process died (or was reaped): the handshake reports how

    def _start(self, name: str, run_id: str, argv: list[str],
               import_path: Sequence[str] = (), one_runtime_thread: bool = True) -> None:
        self.name = name
        self._log = tempfile.TemporaryFile(prefix=f"cosim-{name}-")
        env = _child_env(run_id, import_path, one_runtime_thread)
        self.popen = subprocess.Popen(argv, env=env, stdin=subprocess.PIPE,
                                      stdout=self._log, stderr=subprocess.STDOUT)
        self.pid = self.popen.pid

    def exit_code(self) -> int | None:
        """The exit code if the process has ended (negative: killed by that signal)."""
        return self.popen.poll()

    def end_known(self) -> bool:
        """Whether how the process ended can be told (here: it has an exit code)."""
        return self.exit_code() is not None

    def describe_exit(self) -> str:
        """How the process ended, with the tail of what it printed."""
        code = self.popen.poll()
        if code is None:
            text = STOPPED if process_stopped(self.pid) else (
                "process stopped or not responding (liveliness token lost while it still runs)")
        elif code < 0:
            text = f"process killed by {signal.Signals(-code).name}"
        else:
            text = f"process exited with code {code}"
        tail = self.log_tail()
        return f"{text}; last output: {tail}" if tail else text

    def log_tail(self) -> str:
        """The last lines the process printed (stdout and stderr), stripped."""
        return file_tail(self._log, TAIL_CHARS)

    def close_log(self) -> None:
        """Release the log file."""
        self._log.close()


def file_tail(log: Any, chars: int) -> str:
    """The last `chars` bytes of an open binary file (a child's log), decoded and stripped;
    '' when it cannot be read (closed, removed)."""
    try:
        log.seek(0, os.SEEK_END)
        log.seek(max(0, log.tell() - chars))
        return log.read().decode(errors="replace").strip()
    except (OSError, ValueError):
        return ""


def process_state(pid: int) -> str:
    """The state letter of process `pid` from /proc ("R", "S", "T", "Z", ...); "" when it is gone."""
    try:
        stat_line = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    return stat_line.rpartition(")")[2].split()[0]


def process_stopped(pid: int) -> bool:
    """Whether process `pid` is stopped (SIGSTOP, SIGTSTP, a debugger), from /proc."""
    return process_state(pid) in ("T", "t")


def reap(children: list[ChildProcess], grace_s: float) -> None:
    """End every child: SIGTERM (and SIGCONT, for a stopped one) those still running,
    SIGKILL whatever is left after `grace_s`; always waits so no zombie remains.

    Args:
        children: the processes to end.
        grace_s: seconds given to the processes before they are killed.
    """
    deadline = time.monotonic() + grace_s
    for child in children:
        if child.exit_code() is None:
            try:
                child.popen.terminate()
                child.popen.send_signal(signal.SIGCONT)  # a stopped process must run to end
            except ProcessLookupError:
                pass
    for child in children:
        try:
            child.popen.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            child.popen.kill()
            child.popen.wait()
        child.close_log()
        stdin = getattr(child.popen, "stdin", None)  # a prestarted process's pipe
        if stdin is not None:
            stdin.close()
