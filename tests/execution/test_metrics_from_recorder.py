"""A run's metrics come from the recorder's rows (cosim.execution.finish): they are the
metrics of its signals.csv, parsed back, to the bit."""

from __future__ import annotations

import shutil

import cosim
from cosim.analysis.metrics import platform_metric, write_metrics
from cosim.analysis.rundata import load_run


def test_the_metrics_of_a_run_are_those_of_its_every_tick(tmp_path):
    run = cosim.run("obstacle_avoidance", set={"duration": 6.0}, out=tmp_path / "run")
    assert run.status == "ok" and sum(map(platform_metric, run.metrics)) > 10
    decimated = cosim.run("obstacle_avoidance", set={"duration": 6.0, "record.every": 4},
                          out=tmp_path / "decimated")
    assert decimated.metrics == run.metrics  # from every tick, whatever the files keep
    again = tmp_path / "again"
    shutil.copytree(tmp_path / "run", again)
    write_metrics(again, run=load_run(again))  # signals.csv parsed, as `cosim metrics` does
    assert (again / "metrics.json").read_text() == (tmp_path / "run" / "metrics.json").read_text()
