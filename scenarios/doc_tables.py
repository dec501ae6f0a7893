"""The results tables of README.md and scenarios/README.md, generated from matrix runs.

    python -m scenarios.matrix --out DIR --write-docs

runs the whole matrix and the Satory disturbance variants (SATORY_VARIANTS),
then rewrites every generated block of the two READMEs. A block sits between

    <!-- generated: NAME (python -m scenarios.matrix --write-docs) -->
    <!-- end generated: NAME -->

and nothing outside the markers is touched. Blocks: `summary` (both files: max
|yc_cg| / max |yc| per scenario and controller on Vehicle8DOF, cone hits,
final friction estimate), `satory_cost` (scenarios/README.md: what the model
error and the wind cost on Satory) and `full` (scenarios/README.md: every run,
every metric). tests/scenarios/test_doc_tables.py checks that the blocks hold
what the code computes now.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from scenarios.matrix import (CONTROLLERS, SCENARIO_DIR, MatrixRow, markdown_rows, run_one)

REPO = SCENARIO_DIR.parent
DOCS = {REPO / "README.md": ("summary",), SCENARIO_DIR / "README.md": ("summary", "satory_cost", "full")}
SUMMARY_PLANT = "Vehicle8DOF"
#: scenarios of the summary table, in order (obstacle_blocked and open_loop have no lateral error)
SUMMARY_SCENARIOS = ("satory_nominal", "satory_disturbed", "opendrive_loop", "lane_keeping",
                     "lane_change", "obstacle_avoidance", "friction_drop", "iso3888_2")
ADAPTIVE = ("bs_robust_ff", "bs_adaptive_ff", "bs_adaptive_faithful")
#: (row label, scenario, overrides): Satory with one disturbance at a time, on SUMMARY_PLANT
SATORY_VARIANTS = (
    ("nominal", "satory_nominal", ()),
    ("+ drag (aero alone, Fig. 4.4)", "satory_disturbed",
     ("sources.side_wind.points=[[0, 0]]", "components.vehicle.uncertainty={}")),
    ("+ drag + 30 % error", "satory_disturbed", ("sources.side_wind.points=[[0, 0]]",)),
    ("+ drag + wind", "satory_disturbed", ("components.vehicle.uncertainty={}",)),
    ("+ drag + 30 % + wind (satory_disturbed)", "satory_disturbed", ()),
)
BEGIN = "<!-- generated: {name} (python -m scenarios.matrix --write-docs) -->"
END = "<!-- end generated: {name} -->"


def short(value: float) -> str:
    """A length or speed as the prose tables show it (3 decimals below 1, else 3 digits)."""
    return f"{value:.3f}" if abs(value) < 1.0 else f"{value:.3g}"


def summary_cell(row: MatrixRow) -> str:
    """'yc_cg / yc [cones] (mu_hat)' of one run; 'failed' for a failed run."""
    m = row.metrics
    if row.status != "ok" or "max_abs_yc_cg" not in m:
        return "failed"
    text = f"{short(m['max_abs_yc_cg'])} / {short(m['max_abs_yc'])}"
    if "cone_hits" in m:
        text += f" [{m['cone_hits']}]"
    if row.controller in ADAPTIVE and "mu_hat_final" in m:
        text += f" ({m['mu_hat_final']:.2f})"
    return text


def _grid(head: str, labels: Sequence[str], cell: Callable[[str, str], str]) -> str:
    lines = ["| " + " | ".join([head, *(f"`{c}`" for c in CONTROLLERS)]) + " |",
             "|" + "---|" * (1 + len(CONTROLLERS))]
    lines += ["| " + " | ".join([label, *(cell(label, c) for c in CONTROLLERS)]) + " |"
              for label in labels]
    return "\n".join(lines)


def summary_table(rows: Sequence[MatrixRow]) -> str:
    """The summary block: one line per SUMMARY_SCENARIOS, one column per controller."""
    found = {(r.scenario, r.controller): r for r in rows if r.plant == SUMMARY_PLANT}
    return _grid("scenario", SUMMARY_SCENARIOS,
                 lambda s, c: summary_cell(found[s, c]) if (s, c) in found else "")


def satory_cell(row: MatrixRow) -> str:
    """'yc_cg / yc / rms ex [mu_hat]' of one Satory variant run."""
    m = row.metrics
    if row.status != "ok" or "max_abs_yc_cg" not in m:
        return "failed"
    text = f"{short(m['max_abs_yc_cg'])} / {short(m['max_abs_yc'])} / {short(m['rms_ex'])}"
    if row.controller in ADAPTIVE:
        text += f" [{m['mu_hat_final']:.2f}]"
    return text


def satory_table(variants: Mapping[tuple[str, str], MatrixRow]) -> str:
    """The satory_cost block from the runs of SATORY_VARIANTS, by (label, controller)."""
    return _grid("Satory", [v[0] for v in SATORY_VARIANTS],
                 lambda label, c: satory_cell(variants[label, c]) if (label, c) in variants else "")


def run_satory_variants(out: Path, echo: bool = True) -> dict[tuple[str, str], MatrixRow]:
    """Run every SATORY_VARIANTS x controller on SUMMARY_PLANT under out/satory/."""
    found = {}
    for i, (label, scenario, overrides) in enumerate(SATORY_VARIANTS):
        for controller in CONTROLLERS:
            row = run_one(SCENARIO_DIR / f"{scenario}.yaml", controller, SUMMARY_PLANT,
                          out / "satory" / f"v{i}-{controller}", overrides)
            found[label, controller] = row
            if echo:
                print(f"satory variant {label!r:45s} {controller:20s} {satory_cell(row)}", flush=True)
    return found


def blocks(rows: Sequence[MatrixRow], variants: Mapping[tuple[str, str], MatrixRow]) -> dict[str, str]:
    """Every generated block's text, by block name."""
    return {"summary": summary_table(rows), "satory_cost": satory_table(variants),
            "full": "\n".join(markdown_rows(rows))}


def block_text(text: str, name: str, where: Path | str = "document") -> str:
    """The content of block `name` in a document's text.

    Raises:
        ValueError naming the file and block when the markers are missing.
    """
    pattern = re.escape(BEGIN.format(name=name)) + r"\n(.*?)\n" + re.escape(END.format(name=name))
    match = re.search(pattern, text, flags=re.S)
    if match is None:
        raise ValueError(f"{where}: no generated block {name!r} (markers {BEGIN.format(name=name)!r} "
                         f"... {END.format(name=name)!r})")
    return match.group(1)


def replace_block(text: str, name: str, content: str, where: Path | str = "document") -> str:
    """text with block `name` holding `content` (the markers must be there)."""
    block_text(text, name, where)
    pattern = re.escape(BEGIN.format(name=name)) + r"\n.*?\n" + re.escape(END.format(name=name))
    return re.sub(pattern, lambda _: f"{BEGIN.format(name=name)}\n{content}\n{END.format(name=name)}",
                  text, count=1, flags=re.S)


def write_docs(generated: Mapping[str, str]) -> list[Path]:
    """Rewrite the generated blocks of DOCS; returns the files written."""
    written = []
    for path, names in DOCS.items():
        text = path.read_text()
        for name in names:
            text = replace_block(text, name, generated[name], path)
        path.write_text(text)
        written.append(path)
    return written
