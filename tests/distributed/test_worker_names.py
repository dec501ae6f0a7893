"""Workers: a name two workers answer to is refused before the run starts (and
listed twice by `cosim workers`), discovery waits without spinning, `--allow`
adds to the default allow-list, and a worker that cannot start leaves no FMU
cache folder behind."""

from __future__ import annotations

import glob
import os
import socket
import subprocess
import sys
import tempfile
import time

import pytest

from cosim.distributed import protocol as proto
from cosim.distributed.client import DistributedComponents, list_workers, query_workers
from cosim.distributed.deploy import DeploySettings, zenoh_config
from cosim.distributed.worker import Worker
from cosim.errors import UserError
from cosim.transport.zenoh.config import free_tcp_endpoint
from tests.distributed.test_worker import WorkerThread, settings_for
from tests.helpers.components import launch, run_processes
from tests.helpers.credentials import shared_auth
from tests.helpers.paths import REPO_ROOT

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]


def test_a_name_answered_by_two_workers_is_refused_naming_both():
    first, second = free_tcp_endpoint(), free_tcp_endpoint()
    agents = [WorkerThread("wdup", DeploySettings(listen=[e], auth=shared_auth()))
              for e in (first, second)]
    run_id = f"t-dup-{os.getpid()}"
    try:
        settings = settings_for(first).model_copy(update={"connect": [first, second]})
        listed = list_workers(settings, 1.0)
        assert [(w["name"], w["listen"]) for w in listed] == \
            sorted([("wdup", [first]), ("wdup", [second])], key=lambda row: row[1])
        with pytest.raises(UserError) as error:
            with DistributedComponents([launch("mixer", "Mixer")], run_id, 5.0,
                                       placement={"mixer": "wdup"}, settings=settings):
                pass
        host, pid = socket.gethostname(), os.getpid()
        both = sorted(f"host {host!r} (pid {pid}, listening on {e})" for e in (first, second))
        assert str(error.value) == (f"run {run_id!r}: worker name 'wdup' is answered by 2 "
                                    f"workers: {both[0]}; {both[1]}; give each worker its "
                                    f"own --name")
        assert [a.worker.info()["running"] for a in agents] == [0, 0]  # nothing started
    finally:
        for agent in agents:
            agent.close()
    assert run_processes(run_id) == []


def test_discovery_waits_without_spinning():
    """No worker answers: the query returns at once, the loop must sleep between tries."""
    import zenoh
    session = zenoh.open(zenoh_config(DeploySettings(), "peer", [], []))
    try:
        cpu, wall = time.thread_time(), time.monotonic()
        assert query_workers(session, 1.0, {"nosuch"}) == {}
        cpu, wall = time.thread_time() - cpu, time.monotonic() - wall
    finally:
        session.close()
    assert 0.95 < wall < 1.5
    assert cpu < 0.2, f"discovery used {cpu:.2f} s of CPU in 1 s of waiting"


def test_allow_adds_to_the_defaults_and_refuses_empty_prefixes():
    worker = Worker("wallow", DeploySettings(auth=shared_auth()), ["mypkg."])
    assert worker.allow == ("controllers.", "cosim.sources", "mypkg.")
    assert Worker("wallow", DeploySettings(), proto.DEFAULT_ALLOW).allow == proto.DEFAULT_ALLOW
    for bad, problem in (("", "an empty module prefix would allow every module; give a "
                              "package such as 'mypackage.' or a module such as 'mypackage.x'"),
                         (".", "an empty module prefix would allow every module; give a "
                               "package such as 'mypackage.' or a module such as 'mypackage.x'"),
                         ("a..b", "not a module prefix (dotted Python names, e.g. "
                                  "'mypackage.' or 'mypackage.models')")):
        with pytest.raises(ValueError) as error:
            Worker("wallow", DeploySettings(), [bad])
        assert str(error.value) == f"--allow {bad!r}: {problem}"


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cosim.cli.app", *args], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=60)


def test_cli_allow_empty_prefix_is_one_line_exit_2():
    done = cli("worker", "--name", "wempty", "--listen", "tcp/127.0.0.1:0", "--allow", "")
    assert done.returncode == 2
    assert "Traceback" not in done.stderr and done.stdout == ""
    assert done.stderr.strip().endswith("--allow '': an empty module prefix would allow every "
                                        "module; give a package such as 'mypackage.' or a "
                                        "module such as 'mypackage.x'")
    assert len(done.stderr.strip().splitlines()) == 1


def fmu_folders(name: str) -> list[str]:
    return glob.glob(os.path.join(tempfile.gettempdir(), f"cosim-worker-{name}-fmus-*"))


def test_a_worker_that_cannot_listen_leaves_no_cache_folder():
    name = f"wbusy{os.getpid()}"
    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    holder.listen()
    port = holder.getsockname()[1]
    try:
        worker = Worker(name, DeploySettings(listen=[f"tcp/127.0.0.1:{port}"], auth=shared_auth()))
        with pytest.raises(UserError, match=f"worker '{name}': cannot open its Zenoh session"):
            worker.serve(stop_event=__import__("threading").Event())
        assert fmu_folders(name) == []
        done = cli("worker", "--name", name, "--listen", f"tcp/127.0.0.1:{port}", "--insecure")
        assert done.returncode == 2 and "Traceback" not in done.stderr
        assert f"worker '{name}': cannot open its Zenoh session" in done.stderr
    finally:
        holder.close()
    assert fmu_folders(name) == []


def test_a_served_worker_removes_its_cache_folder_at_the_end():
    name = f"wcache{os.getpid()}"
    agent = WorkerThread(name, DeploySettings(listen=[free_tcp_endpoint()], auth=shared_auth()))
    try:
        assert len(fmu_folders(name)) == 1
    finally:
        agent.close()
    assert fmu_folders(name) == []
