"""run.mcap (cosim.foxglove.mcap_export) read back with the mcap library, against signals.csv."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from cosim.analysis.road import lane_lines, scenario_road
from cosim.analysis.rundata import load_run
from cosim.cli.app import main
from cosim.execution.run import run_scenario
from cosim.foxglove.mcap_export import write_run_mcap
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import SCENARIOS_DIR


@pytest.fixture(scope="module")
def lane_change(tmp_path_factory) -> Path:
    """A 6 s lane-change run (planner windows at 10 Hz) with its run.mcap."""
    out = tmp_path_factory.mktemp("mcap") / "run"
    scenario = load_scenario(SCENARIOS_DIR / "lane_change.yaml", ["duration=6"])
    assert run_scenario(scenario, out, transport="inproc", progress=False).status == "ok"
    write_run_mcap(out)
    return out




def decoded(path: Path, topic: str) -> list:
    with path.open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        return [(m.log_time, d) for _, _, m, d in reader.iter_decoded_messages(topics=[topic])]


def test_channels_schemas_and_counts(lane_change):
    run = load_run(lane_change)
    with (lane_change / "run.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()
    channels = {c.topic: (summary.schemas[c.schema_id], c, summary.statistics.channel_message_counts[i])
                for i, c in summary.channels.items()}
    kinds = {topic: (schema.name, schema.encoding, ch.message_encoding)
             for topic, (schema, ch, _) in channels.items()}
    assert kinds["/tf"] == ("foxglove.FrameTransform", "protobuf", "protobuf")
    for topic in ("/scene/road", "/scene/body", "/scene/planner.ref", "/scene/planner.alt"):
        assert kinds[topic] == ("foxglove.SceneUpdate", "protobuf", "protobuf")
    components = {name.split(".", 1)[0] for name in run.columns}
    for comp in components:
        assert kinds[f"/signals/{comp}"][1:] == ("jsonschema", "json")
    rows = run.time.size
    assert channels["/tf"][2] == rows
    assert all(channels[f"/signals/{c}"][2] == rows for c in components)
    assert channels["/scene/planner.ref"][2] == run.array("planner.ref_x").times.size
    assert channels["/scene/road"][2] == channels["/scene/body"][2] == 1


def test_poses_and_signals_are_the_recorded_values(lane_change):
    run = load_run(lane_change)
    poses = decoded(lane_change / "run.mcap", "/tf")
    for k in (0, len(poses) - 1):
        log_time, tf = poses[k]
        assert log_time == round(run.time[k] * 1e9)
        assert (tf.parent_frame_id, tf.child_frame_id) == ("world", "vehicle")
        assert (tf.translation.x, tf.translation.y) == (run.signal("vehicle.x")[k], run.signal("vehicle.y")[k])
        q = tf.rotation
        yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2))
        assert yaw == pytest.approx(math.remainder(run.signal("vehicle.psi")[k], 2 * math.pi), abs=1e-12)
    with (lane_change / "run.mcap").open("rb") as handle:
        messages = [(m.log_time, json.loads(m.data)) for _, c, m in make_reader(handle).iter_messages(
            topics=["/signals/vehicle"])]
    vx = run.signal("vehicle.vx")
    assert [m["vx"] for _, m in messages] == vx.tolist()      # exact: the CSV's floats
    assert [t for t, _ in messages] == [round(t * 1e9) for t in run.time]


def test_road_and_windows_are_line_strips(lane_change):
    run = load_run(lane_change)
    (_, road), = decoded(lane_change / "run.mcap", "/scene/road")
    lines = lane_lines(scenario_road(run))
    assert len(road.entities[0].lines) == len(lines) == 3      # two edges and one divider
    edge = road.entities[0].lines[0]
    assert (edge.points[0].x, edge.points[0].y) == (lines[0].x[0], lines[0].y[0])
    windows = decoded(lane_change / "run.mcap", "/scene/planner.ref")
    xs = run.array("planner.ref_x")
    last = windows[-1][1].entities[0].lines[0].points
    np.testing.assert_array_equal([p.x for p in last], xs.values[-1])


def test_cli_record_mcap_writes_it_beside_signals(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(SCENARIOS_DIR / "opendrive_loop.yaml"), "--out", str(out), "--transport",
                 "inproc", "--no-figures", "--set", "duration=2", "--set", "record.mcap=true"])
    assert code == 0
    assert f"mcap: {out / 'run.mcap'}" in capsys.readouterr().out
    (_, road), = decoded(out / "run.mcap", "/scene/road")
    assert len(road.entities[0].lines) == 4     # the OpenDRIVE file's borders: lanes -2, -1, 1 and the centre


def test_cosim_mcap_converts_a_run_folder(lane_change, tmp_path, capsys):
    (lane_change / "run.mcap").unlink()
    assert main(["mcap", str(lane_change)]) == 0
    assert (lane_change / "run.mcap").is_file()
    assert main(["mcap", str(tmp_path / "nothing")]) == 2
