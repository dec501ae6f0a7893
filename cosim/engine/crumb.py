"""The master's breadcrumb: one 64-bit word saying which component call is under way.

The master writes it before every call of a component and clears it when the
tick's calls are done (`cosim.engine.master`), and the run around each
constructor of a component in its process (`cosim.execution.run`); a supervisor in another process
reads it through shared memory (`cosim.execution.supervisor`) to name the
component, the call and the tick when the master dies or hangs in native code.
No imports: the supervisor loads this module alone.
"""

from __future__ import annotations

CALL_START, CALL_STEP, CALL_STOP = 1, 2, 3  # kinds of call
CALL_BUILD = 4  # an in-process component's constructor, before the master exists
CALLS = {CALL_START: "start", CALL_STEP: "step", CALL_STOP: "stop", CALL_BUILD: "constructor"}


def crumb_code(index: int, call: int, tick: int = 0) -> int:
    """The word for component `index` (in step order) in `call` at `tick`.

    Bits 0-15: index + 1 (0: no call), bits 16-19: the call kind, from bit 20: the tick.
    """
    return (tick << 20) | (call << 16) | (index + 1)


def decode_crumb(word: int) -> tuple[int, int, int] | None:
    """(component index, call kind, tick) of a word, or None for "no call under way"."""
    if word & 0xFFFF == 0:
        return None
    return (word & 0xFFFF) - 1, (word >> 16) & 0xF, word >> 20
