"""Performance-table rows read from the printed output of the benchmarks that emit no RESULT line.

One function per benchmark (`run_all.BENCHMARKS` names it): stdout in, rows
(`benchmarks.common.table_row`) out. A line that is not found gives no row,
and `run_all` then reports "no figure found": a changed output format shows
in the table instead of a stale figure.
"""

from __future__ import annotations

import re

from benchmarks.common import table_row

FLOAT = r"(-?\d+(?:\.\d+)?)"


def _find(pattern: str, text: str) -> re.Match | None:
    return re.search(pattern, text, re.MULTILINE)


def fmu_step(out: str) -> list[dict]:
    """bench_fmu_step: Vehicle8DOF physics vs fmpy's call overhead; fmpy's per-call host step
    vs the C shim's (the default), with the physics alone beside it (the budget's floor)."""
    rows = []
    null = _find(rf"^Vehicle8DOF\.fmu\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s*$", out)
    if null:
        ratio = float(null.group(6))
        rows.append(table_row("Vehicle8DOF (FMI 2) physics in C / fmpy's per-step call overhead",
                              f"{null.group(4)} vs {null.group(2)} µs: {ratio:.2f}", "< 1", ratio < 1))
    shim = _find(rf"^Vehicle8DOF\.fmu\s+{FLOAT} /\s+{FLOAT}\s+{FLOAT} /\s+{FLOAT}\s+{FLOAT}.*?(\S+)\s*$", out)
    if shim:
        median = float(shim.group(4))
        physics = f"; the model's physics alone {null.group(4)} µs (C loop)" if null else ""
        rows.append(table_row("per-tick FMU host step, Vehicle8DOF (FMI 2): fmpy's per-call path vs the C "
                              "stepping shim (the default), medians",
                              f"{shim.group(2)} vs {shim.group(4)} µs ({shim.group(5)}x), outputs "
                              f"{shim.group(6)}{physics}", "<= 3 µs (issue 14)", median <= 3.0))
    return rows


def master_overhead(out: str) -> list[dict]:
    """bench_master_overhead: what the master adds per tick, three cases."""
    rows = []
    for case in ("scalars", "with trajectory window", "window + recorder"):
        found = _find(rf"^{re.escape(case)}\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s*$", out)
        if found:
            overhead = float(found.group(3))
            rows.append(table_row(f"master overhead per tick, in-process ({case})",
                                  f"{overhead:.1f} µs ({found.group(2)} vs {found.group(1)} direct)",
                                  "< 4 µs", overhead < 4))
    return rows


def closed_loop(out: str) -> list[dict]:
    """bench_closed_loop: the in-process closed loop against 500x real time, one row per mode (interpreted, compiled)."""
    rows = []
    for section in out.split("-- paths: ")[1:]:
        mode = section.split(maxsplit=1)[0]
        total = _find(rf"untimed runs: {FLOAT} us/tick.*?real-time factor {FLOAT}x", section)
        if not total:
            continue
        parts = []
        for label, name in (("controller", "controller"), ("planner", "planner"),
                            ("master overhead", "master"), ("FMU step", "FMU")):
            found = _find(rf"^{re.escape(label)}.*?\s{FLOAT}\s+\d+%\s*$", section)
            if found:
                parts.append(f"{name} {float(found.group(1)):.1f}")
        rtf = float(total.group(2))
        how = ("compiled projection, step and road search (numba)" if mode == "compiled"
               else "interpreted projection, step and road search")
        rows.append(table_row(f"in-process closed loop (Vehicle8DOF + backstepping + planner), 10 ms ticks, {how}",
                              f"{float(total.group(1)):.1f} µs/tick = {rtf:.0f}x real time ({', '.join(parts)} µs)",
                              ">= 500x", rtf >= 500))
    return rows


def libcosim(out: str) -> list[dict]:
    """bench_vs_libcosim: our master against libcosim on the FMU alone."""
    master = _find(rf"^master \(Master \+ FmuComponent\)\s+{FLOAT}\s+{FLOAT}\s*$", out)
    lib = _find(rf"^libcosim \(last-value observer\)\s+{FLOAT}\s+{FLOAT}\s*$", out)
    speed = _find(rf"^master \(Master \+ FmuComponent\)\s+{FLOAT}\s+{FLOAT}\s*$",
                  out[out.find("speed-up"):]) if "speed-up" in out else None
    if not (master and lib and speed):
        not_run = _find(r"^libcosim comparison not run: (.*)$", out)
        return [table_row("our master vs libcosim, FMU alone", f"not run: {not_run.group(1)}", ">= 2x",
                          None)] if not_run else []
    ratio = float(speed.group(1))
    return [table_row("our master vs libcosim on the FMU alone (min µs/step)",
                      f"{master.group(1)} vs {lib.group(1)} µs: {ratio:.2f}x", ">= 2x", ratio >= 2)]


def zenoh(out: str) -> list[dict]:
    """bench_zenoh: a one-component lockstep tick against a raw round trip."""
    raw = _find(rf"^\(a\).*?median\s+{FLOAT} us", out)
    tick = _find(rf"^\(b\).*?median\s+{FLOAT} us", out)
    ratio = _find(rf"^ratio tick / raw \(medians\): {FLOAT}", out)
    if not (raw and tick and ratio):
        return []
    value = float(ratio.group(1))
    rows = [table_row("Zenoh lockstep tick, 1 trivial component / raw put-subscribe round trip (medians), "
                      "processes where the OS puts them",
                      f"{tick.group(1)} vs {raw.group(1)} µs: {value:.2f}", "<= 1.25", value <= 1.25)]
    raw = _find(rf"^\(a1\).*?median\s+{FLOAT} us", out)
    tick = _find(rf"^\(b1\).*?median\s+{FLOAT} us", out)
    ratio = _find(rf"^ratio tick / raw on one CPU \(medians\): {FLOAT}", out)
    if raw and tick and ratio:
        value = float(ratio.group(1))
        rows.append(table_row("the same, every process on one CPU (as `cosim run` from tick 0)",
                              f"{tick.group(1)} vs {raw.group(1)} µs: {value:.2f}", "<= 1.25", value <= 1.25))
    for what, label in (("lockstep tick", "processes where the OS puts them"),
                        ("lockstep tick on one CPU", "every process on one CPU")):
        found = _find(rf"^default pools / one runtime thread, {what}: {FLOAT} / {FLOAT} us = {FLOAT}x", out)
        if found:
            rows.append(table_row(f"the same tick, Zenoh's default runtime pools / one runtime thread "
                                  f"(as a run's processes), {label}",
                                  f"{found.group(1)} vs {found.group(2)} µs: {float(found.group(3)):.2f}x",
                                  "-", None))
    return rows


def startup(out: str) -> list[dict]:
    """bench_startup: `cosim run` to tick 0."""
    rows = []
    labels = {"zenoh": "zenoh", "inproc": "inproc",
              "zenoh-compiled": "zenoh, controller compiled beside the run (a run of 15,000 steps, "
                                "COSIM_JIT=auto, as satory_nominal loads it)",
              "zenoh-compiledfirst": "zenoh, compiled parts loaded before tick 0 (the same run, COSIM_JIT=on)"}
    for transport, label in labels.items():
        found = _find(rf"^{re.escape(transport)}\s+{FLOAT}\s+{FLOAT}\s+{FLOAT}\s+(NOT met|met)\s*$", out)
        if found:
            median = float(found.group(1))
            rows.append(table_row(f"`cosim run` to tick 0, {label} (lane_change)",
                                  f"median {median:.2f} s (min {float(found.group(2)):.2f})", "< 1 s",
                                  median < 1.0))
    walls = {transport: _find(rf"^{re.escape(transport)}\s+{FLOAT} \({FLOAT}-{FLOAT}\); +{FLOAT}\s*$", out)
             for transport in ("zenoh-compiled", "zenoh-compiledfirst")}
    if all(walls.values()):
        beside, first = (float(walls[t].group(1)) for t in ("zenoh-compiled", "zenoh-compiledfirst"))
        rows.append(table_row("`cosim run` whole command, 15,000 steps over Zenoh: compiled parts loaded "
                              "beside the run / before tick 0 (COSIM_JIT=on) (lane_change, medians)",
                              f"{beside:.2f} vs {first:.2f} s: {beside / first:.2f}", "-", None))
    return rows


def foxglove(out: str) -> list[dict]:
    """bench_foxglove: the cost of the live Foxglove view per tick."""
    cases = {}
    for label in ("plain", "server, no client", "client subscribed"):
        found = _find(rf"^\s+{re.escape(label)}\s+{FLOAT} us/tick", out)
        if found:
            cases[label] = float(found.group(1))
    same = _find(r"signals identical in all runs: (True|False)", out)
    if len(cases) < 3:
        return []
    added = cases["server, no client"] - cases["plain"]
    return [table_row("`--foxglove` live view, lane_change in-process (medians)",
                      f"plain {cases['plain']:.0f}, server without client {cases['server, no client']:.0f}, "
                      f"client subscribed {cases['client subscribed']:.0f} µs/tick; signals identical: "
                      f"{same.group(1) if same else '?'}", "~0 added without a client",
                      None if same is None else same.group(1) == "True" and added < 0.1 * cases["plain"])]
