"""What `cosim validate` (and `cosim run`, before t = 0) finds in an FMU's archive
(cosim.fmu.archive): no binary for this platform, a source-only FMU (compiled into
a cached copy), a corrupted entry, a GUID that does not match the binary's, and
variables no host can run. Each is one line naming the file, exit status 2.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

import fmpy
import pytest

from cosim.cli.app import main
from cosim.errors import UserError
from cosim.execution.run import run_scenario
from cosim.execution.validate import validate_scenario
from cosim.scenario.loader import load_scenario

BINARY2 = f"binaries/{fmpy.platform}/Lag.so"


def rewrite_fmu(src: Path, dst: Path, drop: tuple[str, ...] = (),
                replace: dict[str, bytes] | None = None,
                add: dict[str, bytes] | None = None) -> Path:
    """A copy of an FMU without the entries under `drop`, some entries replaced or added."""
    replace, add = replace or {}, add or {}
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            if not info.filename.startswith(drop):
                zout.writestr(info.filename, replace.get(info.filename, zin.read(info)))
        for name, data in add.items():
            zout.writestr(name, data)
    return dst


def scenario(tmp_path: Path, fmu: Path, duration: float = 0.1) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(f"name: s\nduration: {duration}\ntick: 0.01\ncomponents:\n"
                    f"  lag: {{fmu: {fmu}}}\n")
    return path


def validate_error(tmp_path: Path, fmu: Path) -> str:
    with pytest.raises(UserError) as info:
        validate_scenario(load_scenario(scenario(tmp_path, fmu)))
    return str(info.value)


@pytest.mark.parametrize("version", [2, 3])
def test_no_binary_for_this_platform_lists_the_platforms_it_has(tmp_path, test_fmu,
                                                                version) -> None:
    fmu = rewrite_fmu(test_fmu("Lag", version), tmp_path / "win.fmu",
                      drop=("binaries/", "sources/"),
                      add={"binaries/win64/Lag.dll": b"MZ", "binaries/darwin64/Lag.dylib": b"x"})
    folder = fmpy.platform if version == 2 else fmpy.platform_tuple
    assert validate_error(tmp_path, fmu) == (
        f"{tmp_path / 's.yaml'}:5: components.lag.fmu: {fmu}: no binary for this platform "
        f"(binaries/{folder}/Lag.so); the FMU has binaries for: darwin64, win64 and no C "
        "sources to compile")


def test_cli_validate_and_run_exit_2_on_a_missing_binary(tmp_path, test_fmu, capsys) -> None:
    fmu = rewrite_fmu(test_fmu("Lag", 2), tmp_path / "nobin.fmu", drop=("binaries/", "sources/"))
    yaml = scenario(tmp_path, fmu)
    assert main(["validate", str(yaml)]) == 2
    assert main(["run", str(yaml), "--transport", "inproc", "--no-figures",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"error: {yaml}:5: components.lag.fmu: {fmu}: no binary for this platform "
                   f"({BINARY2}); the FMU has binaries for: no platform and no C sources to "
                   "compile"] * 2


@pytest.mark.parametrize("version", [2, 3])
def test_a_source_only_fmu_is_compiled_once_and_runs(tmp_path, test_fmu, monkeypatch,
                                                     version) -> None:
    monkeypatch.setenv("COSIM_CACHE_DIR", str(tmp_path / "cache"))
    original = test_fmu("Lag", version)
    fmu = rewrite_fmu(original, tmp_path / "src.fmu", drop=("binaries/",))
    yaml = scenario(tmp_path, fmu, duration=0.5)
    validate_scenario(load_scenario(yaml))
    compiled = list((tmp_path / "cache" / "compiled-fmus").glob("*/src.fmu"))
    assert len(compiled) == 1 and "binaries/" in str(zipfile.ZipFile(compiled[0]).namelist())
    result = run_scenario(load_scenario(yaml), tmp_path / "run", progress=False)
    reference = run_scenario(load_scenario(scenario(tmp_path, original, duration=0.5)),
                             tmp_path / "ref", progress=False)
    assert result.status == "ok" and result.signals.read_text() == reference.signals.read_text()


def test_sources_that_do_not_compile_say_so(tmp_path, test_fmu, monkeypatch) -> None:
    monkeypatch.setenv("COSIM_CACHE_DIR", str(tmp_path / "cache"))
    fmu = rewrite_fmu(test_fmu("Lag", 2), tmp_path / "broken.fmu", drop=("binaries/",),
                      replace={"sources/model.c": b"#error this model is broken\n"})
    message = validate_error(tmp_path, fmu)
    assert f"{fmu}: no binary for this platform (no binary), and its C sources cannot be " \
           "compiled here: " in message and "this model is broken" in message
    assert len(message.splitlines()) == 1


def test_a_corrupted_entry_fails_its_crc(tmp_path, test_fmu) -> None:
    fmu = rewrite_fmu(test_fmu("Lag", 2), tmp_path / "crc.fmu")
    with zipfile.ZipFile(fmu) as archive:  # rewrite stored: the bytes are in the file as is
        entries = {i.filename: archive.read(i) for i in archive.infolist()}
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_STORED) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    text = entries["sources/model.c"]
    raw = fmu.read_bytes()
    at = raw.index(text)
    fmu.write_bytes(raw[:at] + text.replace(b"exp(", b"EXP(", 1) + raw[at + len(text):])
    assert validate_error(tmp_path, fmu).endswith(
        f"{fmu}: corrupted archive: entry 'sources/model.c' fails its CRC check "
        "(export or copy the FMU again)")


def test_an_archive_checked_once_is_checked_again_when_its_bytes_change(tmp_path, test_fmu) -> None:
    """The checks passed are kept by the file's SHA-256 (a sweep's samples decompress the
    FMU once per worker), so the same path with other bytes is checked afresh."""
    fmu = rewrite_fmu(test_fmu("Lag", 2), tmp_path / "crc.fmu")
    with zipfile.ZipFile(fmu) as archive:
        entries = {i.filename: archive.read(i) for i in archive.infolist()}
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_STORED) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    validate_scenario(load_scenario(scenario(tmp_path, fmu)))  # passes, and is kept
    text = entries["sources/model.c"]
    raw = fmu.read_bytes()
    at = raw.index(text)
    fmu.write_bytes(raw[:at] + text.replace(b"exp(", b"EXP(", 1) + raw[at + len(text):])
    assert validate_error(tmp_path, fmu).endswith("fails its CRC check (export or copy the FMU again)")


@pytest.mark.parametrize("version", [2, 3])
def test_a_guid_the_binary_does_not_hold(tmp_path, test_fmu, version) -> None:
    original = test_fmu("Lag", version)
    xml = zipfile.ZipFile(original).read("modelDescription.xml")
    good = "{9d0c3a51-7b2e-4f3a-8c1d-1a9e0f7a0001}"
    fmu = rewrite_fmu(original, tmp_path / "guid.fmu", replace={"modelDescription.xml": xml.replace(
        good.encode(), b"{00000000-1111-2222-3333-444444444444}")})
    what = "guid" if version == 2 else "instantiationToken"
    assert f"{fmu}: {what} mismatch: modelDescription.xml says " \
           f"'{{00000000-1111-2222-3333-444444444444}}', the binary " in validate_error(tmp_path, fmu)
    assert good in validate_error(tmp_path, fmu)


def test_array_variables_pass_to_the_next_check(tmp_path) -> None:
    """FMI 3 arrays are array signals now (tests/execution/test_typed_signals.py): this
    XML-only FMU gets as far as the binary check."""
    from tests.fmu.test_interface import FMI3_XML, make_fmu

    fmu = make_fmu(tmp_path, FMI3_XML, "arrays.fmu")
    error = validate_error(tmp_path, fmu)
    assert "not supported" not in error and "no binary for this platform" in error
