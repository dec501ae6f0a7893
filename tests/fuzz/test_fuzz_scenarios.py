"""Fuzz: seeded mutations of small scenarios through `cosim validate` and a short
in-process `cosim run`, called in this process through `cosim.cli.app.main`.

Mutations change types, ranges, keys, connections and the YAML text itself
(aliases, nesting, NUL and control bytes, broken UTF-8, truncation). Every case
must end within its time limit, without a traceback, with status 0, 1 (a run
that failed) or 2; a rejection (2) names the scenario file (with a line when the
file has one) or an option. The default variant runs 320 cases; the `slow`
one (`pytest -m slow`) runs 2000 with other seeds.
"""

from __future__ import annotations

import copy
import random
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.fuzz.harness import assert_clean_rejection, run_case

BASE: dict[str, Any] = {
    "name": "fuzz",
    "duration": 0.05,
    "tick": 0.01,
    "components": {
        "gain": {"python": "tests.helpers.components:Gain", "period": 0.01,
                 "parameters": {"k": 3.0}},
        "mixer": {"python": "tests.helpers.components:Mixer", "parameters": {"gain": 0.5}},
    },
    "sources": {
        "ramp": {"kind": "ramp", "start": 0.0, "end": 1.0, "t_start": 0.0, "t_end": 1.0},
        "wind": {"kind": "table", "points": [[0, 1.0], [1, 2.0]]},
    },
    "connections": ["ramp.value -> gain.x", {"from": "gain.y", "to": "mixer.u", "delay": 0}],
    "record": {"include": ["*"], "exclude": []},
}

PLANNER = {  # the planner's geometry is checked by its constructor (in validate)
    "name": "fuzz_planner",
    "duration": 0.05,
    "tick": 0.01,
    "components": {
        "planner": {"python": "controllers.planning:Planner", "period": 0.01, "parameters": {
            "road": {"builder": "two_lane", "length": 300, "radius": 150},
            "lane": 0, "speed": {"v_max": 10.0}, "laps": 1}},
    },
}

ODD_VALUES: list[Any] = [True, False, None, "yes please", "x", "", [], {}, [1, "a"], {"a": 1},
                         0, -1, 1e-9, 1e9, 1e308, -1e308, 10**30, ".nan", ".inf", "1e400",
                         "2024-13-45", "../../../X", "a" * 300, "\u00e9\u00e8", 3.5, [0.1, 0.2]]
ODD_KEYS = ["", "1", "true", "name ", "compnents", "paramters", "from", "<<", "x" * 200]
ODD_CONNECTIONS: list[Any] = ["ramp -> ", "->", "a.b.c -> d", "ramp.value -> nobody.x",
                              "gain.y -> gain.x", {"from": "ramp.value"}, {"to": 1},
                              {"from": "ramp.value", "to": "gain.x", "delay": -1},
                              {"from": "ramp.value", "to": "gain.x", "delay": True},
                              42, None, "mixer.count -> mixer.u"]


def _leaves(node: Any, path: tuple = ()) -> list[tuple]:
    """Every path to a value in the document (mappings and lists included)."""
    found = [path] if path else []
    if isinstance(node, dict):
        for key, value in node.items():
            found += _leaves(value, path + (key,))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            found += _leaves(value, path + (i,))
    return found


def _set(doc: Any, path: tuple, value: Any) -> None:
    for key in path[:-1]:
        doc = doc[key]
    doc[path[-1]] = value


def _parent(doc: Any, path: tuple) -> Any:
    for key in path[:-1]:
        doc = doc[key]
    return doc


def mutate_document(rng: random.Random, doc: dict) -> dict:
    """One to three structural mutations of a scenario document."""
    doc = copy.deepcopy(doc)
    for _ in range(rng.randint(1, 3)):
        paths = _leaves(doc)
        if not paths:
            break
        path = rng.choice(paths)
        kind = rng.choice(["value", "value", "value", "drop", "rename", "extra", "connection"])
        parent = _parent(doc, path)
        if kind == "value":
            _set(doc, path, copy.deepcopy(rng.choice(ODD_VALUES)))
        elif kind == "drop" and isinstance(parent, dict):
            del parent[path[-1]]
        elif kind == "rename" and isinstance(parent, dict):
            parent[rng.choice(ODD_KEYS)] = parent.pop(path[-1])
        elif kind == "extra" and isinstance(parent, dict):
            parent[rng.choice(ODD_KEYS) + "_extra"] = rng.choice(ODD_VALUES)
        elif kind == "connection":
            doc.setdefault("connections", [])
            if isinstance(doc["connections"], list):
                doc["connections"].append(copy.deepcopy(rng.choice(ODD_CONNECTIONS)))
    return doc


BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(9))


def mutate_text(rng: random.Random, text: str) -> bytes:
    """One mutation of the YAML text itself (bytes: some are not UTF-8)."""
    data = text.encode()
    cut = rng.randrange(len(data))
    choice = rng.randrange(12)
    if choice == 0:
        return data[:cut]                                   # truncated
    if choice == 1:
        return data[:cut] + b"\0" + data[cut:]              # NUL byte
    if choice == 2:
        return data[:cut] + bytes([rng.choice([0x07, 0x1b, 0x7f])]) + data[cut:]
    if choice == 3:
        return data[:cut] + b"\xff\xfe" + data[cut:]        # not UTF-8
    if choice == 4:
        return data + b"\n" + BOMB.encode()                 # alias bomb
    if choice == 5:
        return data + b"\ndeep: " + b"[" * 5000 + b"]" * 5000 + b"\n"
    if choice == 6:
        return data + b"\nloop: &loop [1, *loop]\n"         # self-referencing anchor
    if choice == 7:
        return data + b"\nname: again\n"                    # duplicate key
    if choice == 8:
        return data[:cut] + b"\t" + data[cut:]              # a tab where YAML refuses it
    if choice == 9:
        return data + b"\nmerge: &m {<<: *m}\n"
    if choice == 10:
        flipped = bytearray(data)
        flipped[cut] ^= 1 << rng.randrange(8)
        return bytes(flipped)
    return data[:cut] + b": [{" + data[cut:]                # unbalanced flow


def generate_cases(seed: int, count: int) -> list[bytes]:
    """`count` mutated scenario files (bytes), reproducible from `seed`."""
    rng = random.Random(seed)
    cases = []
    for _ in range(count):
        base = PLANNER if rng.random() < 0.08 else BASE
        if rng.random() < 0.3:
            cases.append(mutate_text(rng, yaml.safe_dump(base, sort_keys=False)))
        else:
            cases.append(yaml.safe_dump(mutate_document(rng, base), sort_keys=False,
                                        allow_unicode=True).encode())
    return cases


def _check_cases(tmp_path: Path, capsys: Any, cases: list[bytes]) -> dict[int, int]:
    counts: dict[int, int] = {}
    for i, data in enumerate(cases):
        path = tmp_path / f"case_{i:04d}.yaml"
        path.write_bytes(data)
        code, err = run_case(["validate", str(path)], capsys)
        assert_clean_rejection(code, err, path, f"validate case {i}")
        if code == 0:
            out = tmp_path / f"run_{i:04d}"
            code, err = run_case(["run", str(path), "--transport", "inproc", "--out", str(out),
                                  "--no-figures", "--max-ticks", "500"], capsys)
            assert_clean_rejection(code, err, path, f"run case {i}")
        counts[code] = counts.get(code, 0) + 1
    return counts


def test_generator_is_seeded_and_varied():
    assert generate_cases(7, 40) == generate_cases(7, 40)
    assert len(set(generate_cases(7, 40))) > 30


def test_mutated_scenarios_are_rejected_cleanly(tmp_path, capsys):
    counts = _check_cases(tmp_path, capsys, generate_cases(11, 320))
    assert sum(counts.values()) == 320
    assert counts.get(2, 0) > 150 and counts.get(0, 0) > 5  # mostly rejected, some still run


@pytest.mark.slow
@pytest.mark.parametrize("seed", [101, 202, 303, 404])
def test_many_more_mutated_scenarios(tmp_path, capsys, seed):
    _check_cases(tmp_path, capsys, generate_cases(seed, 500))
