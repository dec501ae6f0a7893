"""Small test components for the Zenoh transport tests (importable by the runner).

Each one has state and non-trivial float arithmetic, so that a bit-identical
comparison with an in-process run means something.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping

import numpy as np

from cosim.component import Component, ComponentError, Port, Value


class Mixer(Component):
    """Scalar and array inputs and outputs with a running state.

    y = gain * sin(t) * u + state, state += y * 1e-3 + sum(w)
    z = cumsum(w) * gain + y / 3
    """

    inputs = (Port("u"), Port("w", size=3))
    outputs = (Port("y"), Port("z", size=3), Port("count"))

    def __init__(self, gain: float = 1.0, fail_at: float | None = None,
                 nan_at: float | None = None) -> None:
        self.gain = float(gain)
        self.fail_at = fail_at
        self.nan_at = nan_at
        self.state = 0.1
        self.count = 0

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        if self.fail_at is not None and t >= self.fail_at:
            raise ZeroDivisionError(f"mixer cannot divide at t={t}")
        w = np.asarray(inputs["w"])
        y = self.gain * math.sin(t) * inputs["u"] + self.state
        self.state += y * 1e-3 + float(w.sum())
        self.count += 1
        z = np.cumsum(w) * self.gain + y / 3.0
        if self.nan_at is not None and t >= self.nan_at:
            z[1] = math.nan
        return {"y": y, "z": z, "count": float(self.count)}

    def finish(self) -> dict[str, float]:
        return {"steps": float(self.count), "state": self.state}


class Echo(Component):
    """Outputs its input plus one: the trivial component of the benchmark."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        return {"y": inputs["u"] + 1.0}


class Sleeper(Component):
    """Sleeps `seconds` in every step after `after` (s): a component that hangs."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def __init__(self, seconds: float = 3600.0, after: float = 0.0) -> None:
        self.seconds = seconds
        self.after = after

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        if t > self.after:
            time.sleep(self.seconds)
        return {"y": inputs["u"]}


class BadParameter(Component):
    """Rejects a negative `mass` in its constructor."""

    outputs = (Port("y"),)

    def __init__(self, mass: float = 1.0) -> None:
        if mass < 0:
            raise ComponentError(f"mass must be positive, got {mass}")
        self.mass = mass

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        return {"y": self.mass}


class ExitsInInit(Component):
    """A process that dies while building its component, before the handshake."""

    outputs = (Port("y"),)

    def __init__(self, code: int = 3) -> None:
        import os
        os._exit(code)


# ---------------------------------------------------------------- test helpers

def launch(name: str, class_name: str, period_ticks: int = 1, **parameters: object):
    """A PythonComponentLaunch of one of the classes above."""
    from cosim.transport.inproc import PythonComponentLaunch
    return PythonComponentLaunch(name, f"tests.helpers.components:{class_name}",
                                 dict(parameters), period_ticks)


def bits(values: Mapping[str, Value]) -> dict[str, tuple[str, bytes]]:
    """Each value's kind and raw float64 bytes, to compare outputs bit for bit."""
    return {name: ("array" if np.ndim(v) else "scalar", np.asarray(v, dtype=np.float64).tobytes())
            for name, v in values.items()}


def run_processes(run_id: str) -> list[int]:
    """Pids of live (non-zombie) component processes of run `run_id` (their
    COSIM_RUN_ID: the run id is not on their command line)."""
    import os
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as f:
                environ = f.read().split(b"\0")
            with open(f"/proc/{entry}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if b"COSIM_RUN_ID=" + run_id.encode() in environ and state != "Z":
            found.append(int(entry))
    return found


class SlowStart(Component):
    """Takes `seconds` to construct (many handshake retries meanwhile)."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def __init__(self, seconds: float = 1.0) -> None:
        time.sleep(seconds)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        return {"y": 2.0 * inputs["u"]}


class Gain(Component):
    """y = k * x; NaN at t == fail_at, raises at t == raise_at (for failure tests)."""

    inputs = (Port("x"),)
    outputs = (Port("y"),)

    def __init__(self, k: float = 2.0, fail_at: float = -1.0, raise_at: float = -1.0):
        self.k, self.fail_at, self.raise_at = k, fail_at, raise_at

    def step(self, t, inputs):
        if t == self.fail_at:
            return {"y": math.nan}
        if t == self.raise_at:
            raise ValueError("omega[fl] left its range: [nan 1.0] [red]x[/red]")
        return {"y": self.k * inputs["x"]}


GOOD = """\
name: gain_demo
duration: 0.5
tick: 0.01
components:
  gain:
    python: tests.helpers.components:Gain
    parameters: {k: 3.0}
sources:
  ramp:
    kind: ramp
    start: 0.0
    end: 1.0
    t_start: 0.0
    t_end: 1.0
connections:
  - {from: ramp.value, to: gain.x}
"""


class PController(Component):
    """u = kp (ref - y)."""

    inputs = (Port("ref"), Port("y"))
    outputs = (Port("u"),)

    def __init__(self, kp: float = 1.0):
        self.kp = kp
        self.steps = 0

    def step(self, t, inputs):
        self.steps += 1
        return {"u": self.kp * (inputs["ref"] - inputs["y"])}

    def finish(self):
        return {"steps": float(self.steps)}


class Segfault(Component):
    """Echoes u until t reaches `at`, then reads address 0 (SIGSEGV in this process)."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def __init__(self, at: float = 0.1):
        self.at = at

    def step(self, t, inputs):
        if t >= self.at - 1e-9:
            import ctypes

            ctypes.string_at(0)
        return {"y": inputs["u"]}


class OutputReader(Component):
    """Reports what `use_outputs` told it: `heard` = 1 (called before initialize) + 2 if array
    output `a` is read + 4 if array output `b` is read; 0 if never called. `fail` makes
    `use_outputs` raise."""

    inputs = (Port("u"),)
    outputs = (Port("y"), Port("heard"), Port("a", size=3), Port("b", size=3))

    def __init__(self, fail: bool = False):
        self.fail = fail
        self.told: frozenset[str] | None = None
        self.initialized = False

    def use_outputs(self, names):
        if self.fail:
            raise ValueError("refusing the names")
        self.heard = 1.0 * (not self.initialized) + 2.0 * ("a" in names) + 4.0 * ("b" in names)
        self.told = frozenset(names)

    def initialize(self, t0, inputs):
        self.initialized = True
        return self.step(t0, inputs)

    def step(self, t, inputs):
        heard = self.heard if self.told is not None else 0.0
        return {"y": inputs["u"], "heard": heard, "a": np.full(3, t), "b": np.full(3, -t)}


class Tracker(Component):
    """Scalar and array inputs, interleaved; scalar outputs; stepped on plain values
    (`step_values`, the master's values lane in-process), `step` a thin wrapper over it.

    u = k * tanh(mean(ref) - x) + tanh(v * dot(w, ref)) / 4, integral += u * 1e-2,
    energy = integral ** 2 / 2 (or `bad` from t >= bad_at on).
    """

    inputs = (Port("x"), Port("ref", size=3), Port("v"), Port("w", size=3))
    outputs = (Port("u"), Port("integral"), Port("energy"))
    input_names = tuple(port.name for port in inputs)
    output_names = tuple(port.name for port in outputs)

    def __init__(self, k: float = 0.8, bad: float = math.nan, bad_at: float | None = None):
        self.k, self.bad, self.bad_at = k, bad, bad_at
        self.integral = 0.25
        self.steps = 0
        self.received: list[tuple] = []  # the input arrays of every step, to check they are read-only

    def step_values(self, t: float, inputs: tuple) -> list[float]:
        x, ref, v, w = inputs
        self.received.append((ref, w))
        self.steps += 1
        u = self.k * math.tanh(float(np.mean(ref)) - x) + math.tanh(v * float(np.dot(w, ref))) / 4.0
        self.integral += u * 1e-2
        energy = 0.5 * self.integral ** 2
        if self.bad_at is not None and t >= self.bad_at:
            energy = self.bad
        return [u, self.integral, energy]

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        values = self.step_values(t, tuple(inputs[name] for name in self.input_names))
        return dict(zip(self.output_names, values))

    def finish(self) -> dict[str, float]:
        return {"steps": float(self.steps)}


class TrackerWithoutLane(Tracker):
    """The same component without `step_values`: the master steps it on mappings."""

    step_values = None  # type: ignore[assignment]

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        values = Tracker.step_values(self, t, tuple(inputs[name] for name in self.input_names))
        return dict(zip(self.output_names, values))


class InputOrder(Component):
    """Outputs the order its inputs mapping iterates in, as digits (a=1, w=2, b=3): what a
    component that loops over `inputs` sees must not depend on the transport."""

    inputs = (Port("a"), Port("w", size=3), Port("b"))
    outputs = (Port("order"),)
    DIGITS = {"a": "1", "w": "2", "b": "3"}

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        return {"order": float("".join(self.DIGITS[name] for name in inputs))}


class ShortLane(Tracker):
    """Tracker whose `step_values` returns one value too few (or a generator, `generator=True`);
    its `step` (hence its initialization) is Tracker's."""

    def __init__(self, generator: bool = False) -> None:
        super().__init__()
        self.generator = generator

    def step_values(self, t: float, inputs: tuple):
        values = Tracker.step_values(self, t, inputs)
        return (v for v in values) if self.generator else values[:-1]

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        values = Tracker.step_values(self, t, tuple(inputs[name] for name in self.input_names))
        return dict(zip(self.output_names, values))


class StepsSeen(Component):
    """Outputs the `cosim.component.expected_steps()` its constructor saw (-1: None)."""

    inputs = ()
    outputs = (Port("steps"),)

    def __init__(self) -> None:
        from cosim.component import expected_steps

        seen = expected_steps()
        self.seen = -1.0 if seen is None else float(seen)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        return {"steps": self.seen}


class ConstructorFault(Component):
    """A constructor that never returns: it sleeps (`mode` "hang") or crashes its
    process with a segfault ("segfault")."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def __init__(self, mode: str = "hang") -> None:
        if mode == "segfault":
            import ctypes
            ctypes.string_at(0)  # reads address 0: SIGSEGV
        while True:
            time.sleep(3600)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        return {"y": inputs["u"]}


class RaisesBaseException(Component):
    """Echoes u until t reaches `at`, then calls sys.exit(`code`) (`what` "exit") or
    raises KeyboardInterrupt ("interrupt") from its step."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def __init__(self, what: str = "exit", code: int = 0, at: float = 0.1) -> None:
        self.what, self.code, self.at = what, code, at

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        if t >= self.at - 1e-9:
            if self.what == "exit":
                import sys
                sys.exit(self.code)
            raise KeyboardInterrupt
        return {"y": inputs["u"]}


class ChangesDirectory(Component):
    """Changes the process's working directory in its steps (as some foreign FMUs do)."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        import os
        os.chdir("/")
        return {"y": inputs["u"]}


class FailsToFinish(Echo):
    """Echo whose finish() raises: a failure after the last tick."""

    def finish(self) -> dict[str, float]:
        raise ValueError("cannot summarize")
