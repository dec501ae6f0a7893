"""Start the Zenoh component processes while `cosim run` is still loading the scenario.

A component process spends most of its start-up loading numpy and zenoh,
which does not depend on the scenario. `prestart_components` reads the
scenario file as plain YAML (no validation: that comes after), starts one
process per local Python component and source with `ChildProcess.prestart`
(which also preloads the module its class path names), and `run_scenario`
later hands each its class, parameters and period. A
process the validated scenario does not use (another transport, a component
placed on a worker, a name changed by --set) is ended; `Prestart.close` ends
every one that is left, whatever happened.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.scenario.imports import import_roots
from cosim.transport.zenoh.auth import Credential, new_credential
from cosim.transport.zenoh.processes import ChildProcess, reap

GRACE_S = 2.0


@dataclass
class Prestart:
    """Component processes started before the scenario was validated.

    Attributes:
        run_id: the run id they were started with (the run must use it).
        endpoint: the master endpoint they will connect to.
        credential: the run's credential they will present (the run must use it).
        children: component name -> process.
    """

    run_id: str
    endpoint: str
    credential: Credential
    children: dict[str, ChildProcess] = field(default_factory=dict)

    def close(self) -> None:
        """End every process still running (a used one has been stopped already)."""
        reap(list(self.children.values()), GRACE_S)


SOURCES_MODULE = "cosim.sources"  # where every source kind's class lives (SOURCE_CLASSES)


def local_python_components(document: Any) -> dict[str, str | None]:
    """Name -> module to preload, of the Python components and sources a raw
    scenario runs locally (module None when the class path is not a string).

    Args:
        document: the scenario file parsed as plain YAML.
    """
    if not isinstance(document, dict):
        return {}
    found: dict[str, str | None] = {}
    for section in ("components", "sources"):
        entries = document.get(section) or {}
        if not isinstance(entries, dict):
            continue
        for name, spec in entries.items():
            if not isinstance(spec, dict) or spec.get("host") not in (None, "local"):
                continue
            if section == "sources":
                found[str(name)] = SOURCES_MODULE
            elif "python" in spec:
                path = spec["python"]
                module = path.partition(":")[0] if isinstance(path, str) else ""
                found[str(name)] = module or None
    return found


def local_python_names(document: Any) -> list[str]:
    """Names of the Python components and sources a raw scenario runs locally.

    Args:
        document: the scenario file parsed as plain YAML.
    """
    return list(local_python_components(document))


def prestart_components(scenario_file: str | Path) -> Prestart | None:
    """Start a process for each local Python component of a scenario file.

    Args:
        scenario_file: the scenario YAML (read without validation).
    Returns:
        The started processes, or None when the file cannot be read as YAML or
        names no local Python component (the run then starts them itself).
    """
    import yaml

    from cosim.scenario.yaml_lines import read_yaml_file
    from cosim.transport.zenoh.config import check_key_chunk, free_tcp_endpoint

    try:
        text = read_yaml_file(scenario_file)  # bounded: /dev/zero or a huge file is refused
        document = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        found = local_python_components(document)
        names = [check_key_chunk(n, "component name") for n in found]
    except (OSError, ValueError, yaml.YAMLError, RecursionError):
        return None  # loading the scenario reports it properly (deep nesting included)
    if not names or len(set(names)) != len(names):
        return None
    run_id = uuid.uuid4().hex[:12]
    prestart = Prestart(run_id, free_tcp_endpoint(), new_credential(run_id))
    roots = import_roots(scenario_file)
    try:
        for name in names:
            prestart.children[name] = ChildProcess.prestart(
                name, prestart.run_id, prestart.endpoint, found[name], roots, prestart.credential)
    except BaseException:
        prestart.close()
        raise
    return prestart
