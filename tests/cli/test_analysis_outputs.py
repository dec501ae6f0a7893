"""Default output folders of `cosim compare` and `cosim sweep` stay out of runs/,
and compare skips arguments that are compare or sweep outputs."""

from __future__ import annotations

import datetime
from pathlib import Path

from tests.helpers.synthetic_runs import lane_change_run  # noqa: E402

from cosim.cli.app import main  # noqa: E402
from cosim.cli.run import default_run_dir  # noqa: E402
from cosim.cli.analysis import output_folder_kind, stamped_folder  # noqa: E402

NOW = datetime.datetime(2026, 11, 22, 1, 2, 3, tzinfo=datetime.timezone.utc)


def test_stamped_folder_is_utc_stamped_and_fresh(tmp_path):
    first = stamped_folder(tmp_path / "comparisons", "compare", NOW)
    assert first == tmp_path / "comparisons" / "compare-20261122T010203Z"
    first.mkdir(parents=True)
    assert stamped_folder(tmp_path / "comparisons", "compare", NOW).name == \
        "compare-20261122T010203Z-2"
    assert default_run_dir("lane", NOW) == Path("runs") / "lane-20261122T010203Z"


def test_default_compare_output_then_compare_runs_star(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    a = lane_change_run(tmp_path / "runs" / "a")
    b = lane_change_run(tmp_path / "runs" / "b", offset=0.2)
    assert main(["compare", "runs/a", "runs/b"]) == 0
    outputs = list((tmp_path / "comparisons").iterdir())
    assert len(outputs) == 1 and outputs[0].name.startswith("compare-")
    assert output_folder_kind(outputs[0]) == "a cosim compare output"
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["a", "b"]
    capsys.readouterr()
    # an earlier compare output among the arguments is skipped with a note
    (tmp_path / "runs" / "old-compare").mkdir()
    (tmp_path / "runs" / "old-compare" / "compare_metrics.csv").write_text("metric\n")
    out = tmp_path / "cmp2"
    assert main(["compare", str(a), str(b), str(tmp_path / "runs" / "old-compare"),
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert (f"skipped {tmp_path / 'runs' / 'old-compare'}: a cosim compare output, "
            "not a run folder") in captured.err
    header = (out / "compare_metrics.csv").read_text().splitlines()[0]
    assert header == "metric,a,b"


def test_compare_one_run_is_accepted_and_only_outputs_is_an_error(tmp_path, capsys):
    a = lane_change_run(tmp_path / "a")
    assert main(["compare", str(a), "--out", str(tmp_path / "one")]) == 0
    assert (tmp_path / "one" / "compare_metrics.csv").read_text().splitlines()[0] == "metric,a"
    sweep_out = tmp_path / "sw"
    sweep_out.mkdir()
    (sweep_out / "sweep.json").write_text("{}")
    capsys.readouterr()
    assert main(["compare", str(sweep_out), "--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert f"skipped {sweep_out}: a cosim sweep output, not a run folder" in err
    assert f"error: compare: no run folder among the arguments ({sweep_out})" in err
    assert not (tmp_path / "none").exists()


def test_help_of_compare_says_one_or_more(capsys):
    assert main(["compare", "--help"]) == 0
    assert "one or more run folders" in " ".join(capsys.readouterr().out.split())


def test_default_sweep_output_is_under_sweeps(tmp_path, monkeypatch, capsys):
    import cosim.execution.sweep
    from cosim.errors import UserError

    seen = {}

    def fake_run_sweep(scenario, vary, samples, **options):
        seen.update(options)
        raise UserError("stopped before sampling")

    monkeypatch.setattr(cosim.execution.sweep, "run_sweep", fake_run_sweep)
    assert main(["sweep", str(tmp_path / "lane.yaml"), "--vary", "duration=1:2",
                 "--samples", "3", "--seed", "7"]) == 2
    out = seen["out_dir"]
    assert out.parent == Path("sweeps")
    assert out.name.startswith("lane-s7-n3-") and out.name.endswith("Z")
    assert "stopped before sampling" in capsys.readouterr().err
