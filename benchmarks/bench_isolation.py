"""Benchmark: cost per tick of an isolated FMU (`isolate: true`) against the same FMU
in-process and against one raw Zenoh round trip, in one run.

(a) in-process: `FmuComponent.step` of the Vehicle8DOF FMU (the master's host);
(b) isolated: `IsolatedFmu.step` of the same FMU, in its own process over pipes;
(c) raw Zenoh: one put/subscribe round trip of 100 bytes to an echo process
    (`bench_zenoh.RawPair`, peer mode on 127.0.0.1).
Measured in alternating blocks (the machine's load weighs on all alike); prints
the medians, what isolation adds per tick, and its ratio to the raw round trip
(target: at most 1, i.e. isolation adds at most one raw round trip per tick).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_isolation.py [--ticks 5000] [--blocks 10]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_zenoh import RawPair  # noqa: E402
from cosim.fmu.build import ensure_fmu  # noqa: E402
from cosim.fmu.host import FmuComponent  # noqa: E402
from cosim.fmu.interface import describe_fmu  # noqa: E402
from cosim.fmu.isolated import IsolatedFmu  # noqa: E402


class Stepper:
    """One FMU host started at t = 0 and stepped tick after tick with fixed inputs."""

    def __init__(self, host) -> None:  # noqa: ANN001
        self.host, self.tick = host, 0
        self.inputs = {p.name: 0.0 for p in host.inputs} | {"torque": 100.0, "mu": 1.0}
        host.start(0.0, self.inputs)

    def measure(self, count: int) -> list[float]:
        times, clock, step = [], time.perf_counter, self.host.step
        for _ in range(count):
            self.tick += 1
            start = clock()
            step(self.tick, self.tick * 0.01, self.inputs)
            times.append(clock() - start)
        return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=5000)
    parser.add_argument("--blocks", type=int, default=10)
    args = parser.parse_args()
    path = Path(ensure_fmu("Vehicle8DOF"))
    interface = describe_fmu(path, {})
    inproc = Stepper(FmuComponent("vehicle", path, interface, {}, 1))
    isolated = Stepper(IsolatedFmu("vehicle", path, interface, {}, {}, 1, 10.0))
    times: dict[str, list[float]] = {"in-process FMU step": [], "isolated FMU step": [],
                                     "raw Zenoh round trip": []}
    with RawPair() as pair:
        for case in (inproc, isolated, pair):
            case.measure(200)  # warm-up
        per_block = max(1, args.ticks // args.blocks)
        for _ in range(args.blocks):
            times["in-process FMU step"] += inproc.measure(per_block)
            times["isolated FMU step"] += isolated.measure(per_block)
            times["raw Zenoh round trip"] += pair.measure(per_block)
    inproc.host.stop()
    isolated.host.stop()
    medians = {}
    for label, samples in times.items():
        data = np.array(samples) * 1e6
        medians[label] = float(np.median(data))
        print(f"{label:<24} median {medians[label]:8.1f} us   p99 "
              f"{np.percentile(data, 99):8.1f} us   (n={data.size})")
    added = medians["isolated FMU step"] - medians["in-process FMU step"]
    ratio = added / medians["raw Zenoh round trip"]
    print(f"isolation adds {added:.1f} us per tick = {ratio:.2f} raw Zenoh round trips "
          f"(target <= 1)")


if __name__ == "__main__":
    main()
