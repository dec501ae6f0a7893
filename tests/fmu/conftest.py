"""Fixtures of tests/fmu/: the test FMUs of tests/fmus/ (`test_fmu`, `open_fmu`,
`run_isolated`, see tests/helpers/fmu_probe.py) and, for the physics tests, the built-in plant FMUs,
built once per session from fmus/ with cosim.fmu.build, and a simulator that
runs one of them through fmpy.simulate_fmu with held or tabulated inputs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

from cosim.fmu import build as fmu_build  # noqa: E402
from tests.helpers import fmu_probe  # noqa: E402
from tests.helpers.fmu_probe import Instance  # noqa: E402
from tests.helpers.paths import TEST_FMUS_DIR as TEST_FMUS  # noqa: E402

INPUTS = ("delta", "torque", "wind_fx", "wind_fy", "mu")


@pytest.fixture(scope="session")
def fmu_folders(tmp_path_factory) -> dict[str, str]:
    """Unzipped FMI 2.0 FMUs of both built-in plants, by model name."""
    out = tmp_path_factory.mktemp("fmus-physics")
    folders = {}
    for model in ("Vehicle8DOF", "Bicycle"):
        path = fmu_build.build_fmu(model, 2, out)
        folders[model] = fmpy.extract(str(path), unzipdir=str(out / f"{path.stem}-unzipped"))
    return folders


class Simulator:
    """Runs a built plant FMU: `run(stop, params, inputs, times, step)`.

    inputs: per input name a constant, or an array over `times` (fmpy
    interpolates linearly; repeat a time to make a step). Every output of the
    result is checked finite.
    """

    def __init__(self, folder: str):
        self.folder = folder

    def run(self, stop_time: float, params: dict | None = None, inputs: dict | None = None,
            times=None, step: float = 0.01) -> np.ndarray:
        times = np.array([0.0, stop_time] if times is None else times, dtype=float)
        values = {"delta": 0.0, "torque": 0.0, "wind_fx": 0.0, "wind_fy": 0.0, "mu": 1.0}
        values.update(inputs or {})
        signal = np.zeros(len(times), dtype=[("time", float)] + [(n, float) for n in INPUTS])
        signal["time"] = times
        for name in INPUTS:
            signal[name] = values[name]
        result = fmpy.simulate_fmu(self.folder, stop_time=stop_time, step_size=step,
                                   output_interval=step, start_values=params or {},
                                   input=signal)
        for name in result.dtype.names:
            assert np.all(np.isfinite(result[name])), f"output {name} is not finite"
        return result


@pytest.fixture(scope="session")
def vehicle8dof(fmu_folders) -> Simulator:
    return Simulator(fmu_folders["Vehicle8DOF"])


@pytest.fixture(scope="session")
def variables_def() -> Path:
    return fmu_build.FMUS_DIR / "Vehicle8DOF" / "variables.def"


@pytest.fixture(scope="session")
def defaults8(fmu_folders) -> dict[str, float]:
    """Start values of the Vehicle8DOF parameters, from its modelDescription.xml."""
    md = fmpy.read_model_description(fmu_folders["Vehicle8DOF"])
    return {v.name: float(v.start) for v in md.modelVariables
            if v.causality == "parameter"}


# --- the test FMUs of tests/fmus/ (Faulty, FaultyOnce, BouncingBall, ...)

_BUILT: dict[tuple[str, int], Path] = {}


@pytest.fixture(scope="session")
def test_fmu(tmp_path_factory):
    """Factory: (model folder name under tests/fmus/, FMI version) -> built .fmu path."""
    out = tmp_path_factory.mktemp("test-fmus")

    def build(model: str, version: int) -> Path:
        key = (model, version)
        if key not in _BUILT:
            _BUILT[key] = fmu_build.build_fmu_from(TEST_FMUS / model, version, out)
        return _BUILT[key]

    return build


@pytest.fixture
def open_fmu(tmp_path):
    """Factory: (fmu path, interface="CoSimulation", logging_on=False, unzip=None) -> Instance.

    `unzip`: the extraction folder of another Instance (`inst.unzip`), to load
    the very same binary again (as an importer does for a second instance);
    by default each instance gets its own extraction. Raises InstantiationFailed.
    """
    opened: list[Instance] = []

    def open_(path: Path, interface: str = "CoSimulation", logging_on: bool = False,
              unzip: str | None = None) -> Instance:
        inst = Instance(Path(path), interface, tmp_path, logging_on, unzip)
        opened.append(inst)
        return inst

    yield open_
    for inst in opened:
        if not inst.freed:
            try:
                inst.free()
            except Exception:  # an instance after Fatal may refuse; the test is over anyway
                pass


@pytest.fixture
def run_isolated():
    """Factory: (fmu, start_values, stop_time=1, output_interval=0.1, timeout=60) -> IsolatedRun."""
    return fmu_probe.run_isolated
