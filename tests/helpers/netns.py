"""Network namespaces standing for hosts, for the distributed-run tests.

    with NetLab(["a", "b"]) as lab:            # creates; always removes on exit
        lab.address("a")                        # "10.77.N.2"
        subprocess.Popen(lab.exec("a", [python, "-m", "cosim.cli.app", "worker", ...]))
        lab.link_down("b")                      # cut host b off the network

Topology: a "master" namespace holds a bridge with address 10.77.N.1/24; each
host namespace is joined to that bridge by a veth pair and gets 10.77.N.k/24.
Names carry the test process's pid so concurrent test runs never collide;
every address lives inside the namespaces only. `unavailable()` says why
namespaces cannot be made here (not root, no `ip`), or None.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import uuid
from collections.abc import Sequence

MASTER = "master"


def unavailable() -> str | None:
    """Why this machine cannot create network namespaces for the tests, or None."""
    if shutil.which("ip") is None:
        return "the `ip` command (iproute2) is not installed"
    if os.geteuid() != 0:
        return "creating network namespaces needs root"
    probe = f"czp{uuid.uuid4().hex[:8]}"
    made = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if made.returncode != 0:
        return f"`ip netns add` failed: {made.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


def _ip(*args: str) -> None:
    done = subprocess.run(["ip", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {done.stderr.strip()}")


class NetLab:
    """A master namespace with a bridge and one namespace per host.

    Args:
        hosts: short host names (letters/digits), e.g. ["a", "b"].
        subnet: third byte N of 10.77.N.0/24 (default: derived from the pid).
    """

    def __init__(self, hosts: Sequence[str], subnet: int | None = None) -> None:
        tag = f"{os.getpid() % 100000}{uuid.uuid4().hex[:3]}"
        self.prefix = f"cz{tag}"
        self.subnet = subnet if subnet is not None else 1 + os.getpid() % 250
        self.hosts = [MASTER, *hosts]
        self.namespaces = {h: f"{self.prefix}-{h}" for h in self.hosts}
        self._veth = {h: f"{self.prefix}{i}" for i, h in enumerate(self.hosts) if h != MASTER}
        self._made: list[str] = []

    def address(self, host: str) -> str:
        """IPv4 address of `host` ("master" included)."""
        return f"10.77.{self.subnet}.{self.hosts.index(host) + 1}"

    def exec(self, host: str, argv: Sequence[str]) -> list[str]:
        """`argv` wrapped to run inside the namespace of `host`."""
        return ["ip", "netns", "exec", self.namespaces[host], *argv]

    def __enter__(self) -> "NetLab":
        try:
            self._create()
        except BaseException:
            self.remove()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.remove()

    def _create(self) -> None:
        master = self.namespaces[MASTER]
        for host in self.hosts:
            _ip("netns", "add", self.namespaces[host])
            self._made.append(self.namespaces[host])
            _ip("-n", self.namespaces[host], "link", "set", "lo", "up")
        _ip("-n", master, "link", "add", "br0", "type", "bridge")
        _ip("-n", master, "addr", "add", f"{self.address(MASTER)}/24", "dev", "br0")
        _ip("-n", master, "link", "set", "br0", "up")
        for host, veth in self._veth.items():
            ns = self.namespaces[host]
            _ip("-n", master, "link", "add", f"{veth}m", "type", "veth", "peer", "name",
                f"{veth}h", "netns", ns)
            _ip("-n", master, "link", "set", f"{veth}m", "master", "br0")
            _ip("-n", master, "link", "set", f"{veth}m", "up")
            _ip("-n", ns, "addr", "add", f"{self.address(host)}/24", "dev", f"{veth}h")
            _ip("-n", ns, "link", "set", f"{veth}h", "up")

    def link_down(self, host: str) -> None:
        """Cut `host` off: its veth end on the bridge goes down."""
        _ip("-n", self.namespaces[MASTER], "link", "set", f"{self._veth[host]}m", "down")

    def link_up(self, host: str) -> None:
        """Join `host` to the bridge again."""
        _ip("-n", self.namespaces[MASTER], "link", "set", f"{self._veth[host]}m", "up")

    def pids(self, host: str) -> list[int]:
        """Processes running inside the namespace of `host`."""
        done = subprocess.run(["ip", "netns", "pids", self.namespaces[host]],
                              capture_output=True, text=True)
        return [int(p) for p in done.stdout.split()]

    def remove(self) -> None:
        """Kill what still runs in the namespaces and delete them (idempotent)."""
        for ns in list(self._made):
            host = next(h for h, n in self.namespaces.items() if n == ns)
            for pid in self.pids(host):
                try:
                    os.kill(pid, signal.SIGCONT)
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for ns in reversed(self._made):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        self._made.clear()
