"""The notebook-style API example runs as written and draws its metric against the gain."""

from __future__ import annotations

import subprocess
import sys

import pytest
from PIL import Image

from tests.helpers.paths import REPO_ROOT

EXAMPLE = REPO_ROOT / "examples" / "lane_change_gain_sweep.py"


@pytest.mark.integration
def test_gain_sweep_example_runs_and_plots(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(EXAMPLE), str(out)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "unit of vehicle.vx: m/s" in proc.stdout
    lines = [line for line in proc.stdout.splitlines() if line.startswith("ke = ")]
    assert [line.split(":")[0] for line in lines] == ["ke = 2", "ke = 4", "ke = 8"]
    for ke in ("2", "4", "8"):
        assert (out / f"ke_{ke}" / "metrics.json").is_file()
    with Image.open(out / "max_abs_yc_vs_ke.png") as image:
        assert image.size == (500, 350)
