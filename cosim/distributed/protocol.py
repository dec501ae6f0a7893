"""What a worker and a master say to each other, and the worker's allow-list.

Keys (no run id: workers outlive runs):
    cosim/workers/<name>              queryable of worker <name>; also its liveliness token
    cosim/<run_id>/exit/<component>   a worker's notice that a component process ended

A request is a JSON object with "op":
    {"op": "info"}
        -> {"ok": true, "name", "host", "pid", "allow": [...], "running": n,
            "max_components": n, "authenticated": bool}
    {"op": "start", "run_id", "run_token", "component", "class_path", "parameters",
     "period_ticks", "connect": [master endpoints], "fmu": {"sha256", "data"}}
        -> {"ok": true, "pid"} or {"ok": false, "error": "..."}
        ("fmu", base64 bytes of the file, only for cosim.fmu.remote:RemoteFmu)
    {"op": "stop", "run_id", "run_token", "component"}
        -> {"ok": true, "exit_code"}
        ("run_token": a secret of the run, the same in its start and stop requests:
        a stop with another token is refused)
A refused or failed request always answers {"ok": false, "error"} naming the worker.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

DEFAULT_ALLOW = ("controllers.", "cosim.sources")
WORKERS_PREFIX = "cosim/workers"


def worker_key(name: str) -> str:
    """Queryable key and liveliness token key of worker `name` ("*": all workers)."""
    return f"{WORKERS_PREFIX}/{name}"


def exit_key(run_id: str, component: str) -> str:
    """Key of the notice a worker puts when the process of `component` ends ("*": all)."""
    return f"cosim/{run_id}/exit/{component}"


def module_allowed(class_path: str, allow: Sequence[str]) -> bool:
    """Whether the module of "module:Class" is under one of the allowed prefixes.

    A prefix ending in "." allows the modules under that package ("controllers."
    allows "controllers.planning.planner"); any other prefix allows that module and its
    submodules ("cosim.sources" allows "cosim.sources" and "cosim.sources.x",
    not "cosim.sources_evil").

    Args:
        class_path: "package.module:ClassName" as sent by the master.
        allow: the worker's allowed module prefixes.
    """
    module = class_path.partition(":")[0]
    if not module or any(not part.isidentifier() for part in module.split(".")):
        return False
    for prefix in allow:
        if prefix.endswith("."):
            if module.startswith(prefix):
                return True
        elif module == prefix or module.startswith(prefix + "."):
            return True
    return False


def check_prefix(prefix: str) -> str:
    """Return `prefix` if it can be an allow-list entry, else raise ValueError naming it.

    An entry is a dotted module name ("mypackage.models") or a package with a
    trailing dot ("mypackage."); an empty prefix would allow every module.

    Args:
        prefix: a value of `cosim worker --allow`.
    """
    text = str(prefix)
    name = text[:-1] if text.endswith(".") else text
    if not name:
        raise ValueError(f"--allow {text!r}: an empty module prefix would allow every module; "
                         f"give a package such as 'mypackage.' or a module such as 'mypackage.x'")
    if any(not part.isidentifier() for part in name.split(".")):
        raise ValueError(f"--allow {text!r}: not a module prefix (dotted Python names, "
                         f"e.g. 'mypackage.' or 'mypackage.models')")
    return text


def encode(document: dict[str, Any]) -> bytes:
    """A request or reply as bytes."""
    return json.dumps(document, separators=(",", ":")).encode()


def decode(data: bytes, what: str) -> dict[str, Any]:
    """Parse a request or reply; ValueError naming `what` when it is not a JSON object.

    Args:
        data: the payload.
        what: e.g. "request to worker 'w1'", for the message.
    """
    try:
        document = json.loads(data.decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{what} is not JSON: {exc}") from None
    if not isinstance(document, dict):
        raise ValueError(f"{what} is not a JSON object")
    return document
