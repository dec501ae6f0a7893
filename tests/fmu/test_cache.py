"""The per-user FMU cache: built on first use, keyed by sources and compiler, never in the package."""

from __future__ import annotations

import shutil

import fmpy
import pytest

from cosim import resources
from cosim.cli.app import main
from cosim.fmu import build, cache


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_first_use_builds_into_the_cache_then_reuses_it(cache_dir, monkeypatch):
    path = cache.builtin_fmu("Bicycle-fmi3")
    assert path.parent.parent == cache_dir / "fmus"
    assert path.parent.name == f"Bicycle-{cache.source_key('Bicycle')}"
    assert fmpy.read_model_description(str(path)).fmiVersion == "3.0"
    package = resources.PACKAGE_DIR.resolve()
    assert package not in path.resolve().parents
    builds = []
    monkeypatch.setattr(build, "build_fmu", lambda *args: builds.append(args))
    assert cache.builtin_fmu("Bicycle-fmi3.fmu") == path
    assert builds == []


def test_the_key_follows_the_sources_and_the_compiler(tmp_path, monkeypatch):
    key = cache.source_key("Bicycle")
    assert key == cache.source_key("Bicycle") and key != cache.source_key("Vehicle8DOF")
    monkeypatch.setattr(cache, "compiler_identity", lambda: "/usr/bin/gcc-99:1:2")
    assert cache.source_key("Bicycle") != key
    monkeypatch.undo()
    copy = tmp_path / "fmus"
    shutil.copytree(build.FMUS_DIR, copy)
    monkeypatch.setattr(build, "FMUS_DIR", copy)
    monkeypatch.setattr(build, "FRAMEWORK_DIR", copy / "framework")
    assert cache.source_key("Bicycle") == key  # same bytes elsewhere: same key
    model_c = copy / "Bicycle" / "model.c"
    model_c.write_text(model_c.read_text() + "\n/* edited */\n")
    assert cache.source_key("Bicycle") != key


def test_unknown_name_names_the_discovered_models(cache_dir):
    with pytest.raises(build.FmuBuildError, match="built-in models: Bicycle, Vehicle8DOF"):
        cache.builtin_fmu("Nope")


def test_models_are_discovered_from_the_folders(tmp_path, monkeypatch):
    (tmp_path / "framework").mkdir()
    for name in ("Zeta", "Alpha"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "variables.def").write_text("")
    (tmp_path / "notes").mkdir()  # no variables.def: not a model
    monkeypatch.setattr(resources, "fmus_dir", lambda: tmp_path)
    assert resources.builtin_models() == ["Alpha", "Zeta"]
    assert resources.builtin_fmu_names() == ("Alpha", "Zeta", "Alpha-fmi3", "Zeta-fmi3")


def test_the_scenario_checks_know_the_discovered_models():
    from cosim.scenario.checks import BUILTIN_FMUS

    assert BUILTIN_FMUS == resources.builtin_fmu_names()
    assert set(BUILTIN_FMUS) >= {"Bicycle", "Vehicle8DOF-fmi3"}


def test_build_fmus_without_model_sources_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(resources, "fmus_dir", lambda: tmp_path)
    assert main(["build-fmus", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "error: no built-in model sources found" in err and "variables.def" in err
    assert not (tmp_path / "out").exists()


def test_build_fmus_default_output(tmp_path, monkeypatch, cache_dir, capsys):
    """A checkout builds into build/fmus; an installed package into the cache runs use."""
    monkeypatch.setattr(build, "MODELS", ["Bicycle"])
    monkeypatch.setattr(build, "find_models", lambda: ["Bicycle"])
    monkeypatch.setattr(resources, "is_checkout", lambda: False)
    assert main(["build-fmus"]) == 0
    printed = capsys.readouterr().out.split()
    assert printed == [str(cache.builtin_fmu("Bicycle")), str(cache.builtin_fmu("Bicycle-fmi3"))]
