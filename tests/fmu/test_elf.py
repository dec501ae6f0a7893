"""`cosim.fmu.elf`: the names a shared library exports, read from its ELF file, against
what the loader sees; the files it refuses, and why."""

from __future__ import annotations

import ctypes
import platform
import subprocess
import zipfile

import pytest

from cosim.fmu.archive import _binary_name, bound_functions
from cosim.fmu.elf import NotASharedLibrary, exported_names
from cosim.fmu.interface import describe_fmu
from tests.helpers.fmus import built_fmu

pytestmark = pytest.mark.skipif(platform.system() != "Linux", reason="ELF files: Linux")


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> bytes:
    """A small library: two functions exported, one hidden, one only used."""
    folder = tmp_path_factory.mktemp("elf")
    (folder / "lib.c").write_text(
        "#include <math.h>\n"
        "double shown_one(double x) { return sin(x); }\n"
        "int shown_two(void) { return 2; }\n"
        "__attribute__((visibility(\"hidden\"))) int hidden(void) { return 3; }\n")
    subprocess.run(["gcc", "-shared", "-fPIC", str(folder / "lib.c"), "-lm", "-o",
                    str(folder / "lib.so")], check=True)
    return (folder / "lib.so").read_bytes()


def test_the_defined_names_are_those_the_loader_finds(library, tmp_path):
    names = exported_names(library)
    assert {"shown_one", "shown_two"} <= names
    assert "hidden" not in names and "sin" not in names  # hidden, and only imported
    path = tmp_path / "lib.so"
    path.write_bytes(library)
    loaded = ctypes.CDLL(str(path))
    for name in ("shown_one", "shown_two"):
        assert hasattr(loaded, name)
    assert not hasattr(loaded, "hidden")


@pytest.mark.parametrize("model, version", [("Vehicle8DOF", 2), ("Vehicle8DOF", 3), ("Bicycle", 2)])
def test_the_built_fmus_export_every_function_fmpy_binds(tmp_path, model, version):
    fmu, _ = built_fmu(tmp_path, model, version)
    interface = describe_fmu(fmu, {})
    exported = exported_names(zipfile.ZipFile(fmu).read(_binary_name(interface)))
    assert len(bound_functions(interface)) > 30 and set(bound_functions(interface)) <= exported


def test_files_that_are_no_library_for_this_machine_are_named(library):
    with pytest.raises(NotASharedLibrary, match=r"^not a shared library \(not an ELF file\)$"):
        exported_names(b"#!/bin/sh\n")
    with pytest.raises(NotASharedLibrary, match="^not a 64-bit little-endian ELF file$"):
        exported_names(library[:4] + b"\x01" + library[5:])
    other = 40 if platform.machine() != "arm" else 62  # EM_ARM
    foreign = library[:18] + other.to_bytes(2, "little") + library[20:]
    with pytest.raises(NotASharedLibrary, match=rf"^built for machine {other}, this machine is "):
        exported_names(foreign)
    with pytest.raises(NotASharedLibrary, match="^a truncated ELF file$"):
        exported_names(library[:200])
