"""The results tables of README.md and scenarios/README.md hold what the code computes now.

The tables are generated (`python -m scenarios.matrix --out DIR --write-docs`,
scenarios/doc_tables.py). By default a cheap subset is re-run and compared with
its cells in every table; the marked slow test (`pytest -m slow`, excluded by
default) re-runs everything and compares each generated block as a whole.
"""
from __future__ import annotations

import pytest

from scenarios import doc_tables as dt
from scenarios.matrix import SCENARIO_DIR, run_matrix, row_line

SUBSET = ("lane_keeping", "bs_robust_ff")


def _summary_cells(text: str, scenario: str) -> dict[str, str]:
    lines = dt.block_text(text, "summary").splitlines()
    head = [c.strip().strip("`") for c in lines[0].strip("|").split("|")]
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        if cells[0] == scenario:
            return dict(zip(head[1:], cells[1:]))
    raise AssertionError(f"summary table has no row {scenario!r}")


def test_every_document_has_its_generated_blocks():
    for path, names in dt.DOCS.items():
        text = path.read_text()
        for name in names:
            assert dt.block_text(text, name, path).strip(), f"{path}: block {name} is empty"


def test_block_replacement_touches_only_the_block():
    text = "before\n" + dt.BEGIN.format(name="x") + "\nold\n" + dt.END.format(name="x") + "\nafter\n"
    new = dt.replace_block(text, "x", "new\nlines")
    assert new == text.replace("\nold\n", "\nnew\nlines\n")
    with pytest.raises(ValueError, match="no generated block 'y'"):
        dt.replace_block(text, "y", "z", "README.md")


def test_cheap_subset_of_the_tables_matches_a_fresh_run(tmp_path):
    scenario, controller = SUBSET
    rows = run_matrix(tmp_path, [scenario], [controller], echo=False)
    assert all(r.status == "ok" for r in rows)
    full = dt.block_text((SCENARIO_DIR / "README.md").read_text(), "full").splitlines()
    columns = [c.strip() for c in full[0].strip("|").split("|")][4:]
    for row in rows:
        assert row_line(row, columns) in full, f"{row.scenario}/{row.controller}/{row.plant}"
    eight = next(r for r in rows if r.plant == dt.SUMMARY_PLANT)
    for path in dt.DOCS:
        assert _summary_cells(path.read_text(), scenario)[controller] == dt.summary_cell(eight), path


@pytest.mark.slow
@pytest.mark.timeout(4 * 3600)  # the whole matrix: far beyond the suite's 300 s per test
def test_every_generated_table_matches_a_fresh_run(tmp_path):
    rows = run_matrix(tmp_path, echo=False)
    generated = dt.blocks(rows, dt.run_satory_variants(tmp_path, echo=False))
    for path, names in dt.DOCS.items():
        text = path.read_text()
        for name in names:
            assert dt.block_text(text, name, path) == generated[name], f"{path}: block {name}"
