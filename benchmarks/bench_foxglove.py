"""Cost per tick of `--foxglove` (no client / a client subscribed to everything) and of run.mcap.

The lane-change scenario runs in-process (`--transport inproc`, the planner's
windows included) several times in alternation: without a live server, with
the server and no client, and with a WebSocket client subscribed to every
channel and draining them. The median wall time per tick of each case and its
difference to the plain run is the live view's cost to the lockstep. The
signals of all runs are compared byte for byte. Then run.mcap is written from
one run folder (after the run: no cost to the lockstep; its own time per tick
is printed too).

Run: .venv/bin/python benchmarks/bench_foxglove.py [--duration S] [--repeats N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from websockets.sync.client import connect  # noqa: E402

from cosim.execution.run import run_scenario  # noqa: E402
from cosim.foxglove.live import FoxgloveLive, static_scene  # noqa: E402
from cosim.foxglove.mcap_export import write_run_mcap  # noqa: E402
from cosim.scenario.loader import load_scenario  # noqa: E402

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "lane_change.yaml"


def drain_everything(url: str, stop: threading.Event, ready: threading.Event, counts: list) -> None:
    """A client that subscribes to every advertised channel and reads until told to stop."""
    with connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=30) as ws:
        next_id = 1
        while not stop.is_set():
            try:
                frame = ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "advertise":
                    subs = [{"id": next_id + i, "channelId": c["id"]} for i, c in enumerate(op["channels"])]
                    next_id += len(subs)
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    ready.set()
            else:
                counts[0] += 1


def one_run(scenario, out: Path, live: FoxgloveLive | None) -> tuple[float, bytes, int]:
    result = run_scenario(scenario, out, transport="inproc", progress=False,
                          observers=[live] if live else [])
    return result.wall_time_s / result.ticks * 1e6, (out / "signals.csv").read_bytes(), result.ticks


def with_client(scenario, out: Path) -> tuple[float, bytes, int, int]:
    live = FoxgloveLive(port=0, static=static_scene(scenario)).start()
    stop, ready, counts = threading.Event(), threading.Event(), [0]
    thread = threading.Thread(target=drain_everything, args=(live.url, stop, ready, counts), daemon=True)
    thread.start()
    # channels are created in begin(): subscribe once they are advertised, with a short warm-up run
    warm = run_scenario(scenario, out / "warm", transport="inproc", progress=False, observers=[live])
    ready.wait(30)
    live.subscriptions.fresh = True
    us, signals, ticks = one_run(scenario, out, live)
    stop.set()
    thread.join(5)
    live.stop()
    return us, signals, ticks, counts[0] if warm.status == "ok" else -1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    scenario = load_scenario(SCENARIO, [f"duration={args.duration}"])
    cases: dict[str, list[float]] = {"plain": [], "server, no client": [], "client subscribed": []}
    signals: set[bytes] = set()
    received = 0
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeats):
            us, sig, ticks = one_run(scenario, Path(tmp) / f"plain{k}", None)
            cases["plain"].append(us)
            signals.add(sig)
            with FoxgloveLive(port=0) as idle:
                us, sig, _ = one_run(scenario, Path(tmp) / f"idle{k}", idle)
            cases["server, no client"].append(us)
            signals.add(sig)
            us, sig, _, got = with_client(scenario, Path(tmp) / f"client{k}")
            cases["client subscribed"].append(us)
            signals.add(sig)
            received += got
        started = time.perf_counter()
        write_run_mcap(Path(tmp) / "plain0")
        mcap_us = (time.perf_counter() - started) / ticks * 1e6
    base = statistics.median(cases["plain"])
    print(f"lane_change, {ticks} ticks of 10 ms, inproc, median of {args.repeats}:")
    for name, values in cases.items():
        median = statistics.median(values)
        print(f"  {name:20s} {median:7.1f} us/tick  ({median - base:+6.1f} us vs plain)")
    print(f"  client received {received} messages; signals identical in all runs: {len(signals) == 1}")
    print(f"  run.mcap after the run: {mcap_us:.1f} us per recorded tick (off the lockstep)")


if __name__ == "__main__":
    main()
