"""Checks of an FMU's archive before t = 0: what `describe_fmu` cannot see in the XML.

`check_archive` holds the .fmu file against what the run will need of it:
every zip entry passes its CRC check, the model description's GUID (FMI 3
instantiationToken) is well formed and, when the binary carries one, the
same as the binary's, and there is a binary for this platform, a shared library
for this machine that exports every FMI function fmpy binds for the interface
(`cosim.fmu.elf`, on Linux; read, not loaded). A source-only
FMU (C sources, no binary for this platform) is compiled once into a cached
copy, as fmpy can (`fmpy.build`, CMake and a C compiler); `check_archive`
then returns that copy's path, which the run loads instead.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import zipfile
import zlib
from pathlib import Path
from typing import Any

from cosim.errors import FmuInterfaceError
from cosim.fmu.interface import file_sha256

_GUID_LIKE = re.compile(rb"\{[0-9A-Fa-f]{8}-[0-9A-Fa-f]{4}-[0-9A-Fa-f]{4}-[0-9A-Fa-f]{4}-"
                        rb"[0-9A-Fa-f]{12}\}")
_LIBRARY_SUFFIX = {"linux": ".so", "darwin": ".dylib", "windows": ".dll"}


# the entry names of archives that passed the CRC and GUID checks in this process, by
# (SHA-256 of the file, GUID, binary): the samples of a sweep on one worker decompress
# an FMU once (testzip reads every entry), whatever path its bytes are found at
ARCHIVES_KEPT = 16
_passed: dict[tuple[str, str, str], tuple[str, ...]] = {}


def check_archive(path: Path, interface: Any, local: bool = True) -> Path:
    """Check an FMU file's archive; the path to load (a compiled copy for a source-only FMU).

    Args:
        path: the .fmu file.
        interface: its `cosim.fmu.interface.FmuInterface`.
        local: the FMU runs on this machine (a worker checks its own platform).
    Raises:
        FmuInterfaceError: a corrupted entry, an empty or mismatched GUID, no
            binary for this platform (naming the platforms the FMU has), or
            sources that do not compile.
    """
    binary = _binary_name(interface)
    names = _checked_names(path, interface, binary)
    if not local or binary in names:
        return path
    platforms = _platforms(names, interface.model_identifier)
    if not any(n.startswith("sources/") and n.endswith(".c") for n in names):
        raise FmuInterfaceError(
            f"{path}: no binary for this platform ({binary}); the FMU has binaries for: "
            f"{', '.join(platforms) or 'no platform'} and no C sources to compile")
    return compiled_copy(path, interface, platforms)


def _checked_names(path: Path, interface: Any, binary: str) -> list[str]:
    """The archive's entry names once its CRC and GUID checks passed (see `_passed`)."""
    key = (file_sha256(path), interface.guid, binary)
    if key not in _passed:
        with zipfile.ZipFile(path) as archive:
            _check_crc(archive, path)
            names = archive.namelist()
            library = archive.read(binary) if binary in names else b""
            _check_guid(interface, path, library)
            if library:
                _check_library(interface, path, binary, library)
        if len(_passed) >= ARCHIVES_KEPT:
            _passed.pop(next(iter(_passed)))  # the oldest
        _passed[key] = tuple(names)
    return list(_passed[key])


def _check_crc(archive: zipfile.ZipFile, path: Path) -> None:
    """Every entry decompresses and matches its CRC-32."""
    try:
        bad = archive.testzip()
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError) as exc:
        raise FmuInterfaceError(f"{path}: corrupted archive: {exc}") from None
    if bad is not None:
        raise FmuInterfaceError(f"{path}: corrupted archive: entry {bad!r} fails its CRC "
                                "check (export or copy the FMU again)")


def _check_guid(interface: Any, path: Path, binary: bytes) -> None:
    """The GUID is not blank and, when the binary holds GUID-like strings, it is one of them."""
    what = "guid" if interface.fmi_version == "2.0" else "instantiationToken"
    guid = interface.guid
    if not guid.strip():
        raise FmuInterfaceError(f"{path}: modelDescription.xml has an empty {what}")
    found = set(_GUID_LIKE.findall(binary))
    if found and _GUID_LIKE.fullmatch(guid.encode()) and guid.encode() not in binary:
        held = ", ".join(sorted(g.decode() for g in found))
        raise FmuInterfaceError(f"{path}: {what} mismatch: modelDescription.xml says {guid!r}, "
                                f"the binary {_binary_name(interface)} holds {held} (the XML "
                                "and the binary come from different exports)")


def _check_library(interface: Any, path: Path, binary: str, library: bytes) -> None:
    """The binary is a shared library for this machine exporting every function fmpy
    binds when it loads the FMU for this interface (Linux; elsewhere nothing is checked)."""
    import fmpy

    from cosim.fmu.elf import NotASharedLibrary, exported_names

    if fmpy.system != "linux":
        return
    try:
        exported = exported_names(library)
    except NotASharedLibrary as exc:
        raise FmuInterfaceError(f"{path}: {binary}: {exc}") from None
    if exported is None:
        return  # no dynamic symbol table to read: loading it will tell
    missing = sorted(set(bound_functions(interface)) - exported)
    if missing:
        listed = ", ".join(missing[:6]) + (f" and {len(missing) - 6} more" if len(missing) > 6 else "")
        raise FmuInterfaceError(f"{path}: {binary} does not export {listed}, which every FMI "
                                f"{interface.fmi_version} {interface.fmi_type} FMU must")


def bound_functions(interface: Any) -> list[str]:
    """The FMI functions fmpy binds when it loads an FMU for this interface (all those of
    its class: the standard's list for the version and interface)."""
    if interface.fmi_version == "2.0":
        from fmpy.fmi2 import FMU2Model, FMU2Slave

        cls, prefix = (FMU2Model if interface.fmi_type == "ModelExchange" else FMU2Slave), "fmi2"
    else:
        from fmpy.fmi3 import FMU3Model, FMU3Slave

        cls, prefix = (FMU3Model if interface.fmi_type == "ModelExchange" else FMU3Slave), "fmi3"
    return [name for name in dir(cls) if name.startswith(prefix)]


def _binary_name(interface: Any) -> str:
    """The archive path of this platform's shared library of the FMU."""
    import fmpy

    folder = fmpy.platform if interface.fmi_version == "2.0" else fmpy.platform_tuple
    return f"binaries/{folder}/{interface.model_identifier}{_LIBRARY_SUFFIX[fmpy.system]}"


def _platforms(names: list[str], identifier: str) -> list[str]:
    """The platform folders under binaries/ that hold the model's library."""
    found = {n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") == 2
             and Path(n).stem == identifier and Path(n).suffix in _LIBRARY_SUFFIX.values()}
    return sorted(found)


def compile_cache_dir() -> Path:
    """Where compiled copies of source-only FMUs are kept (beside the built-in FMUs' cache)."""
    from cosim.fmu.cache import cache_root

    return cache_root() / "compiled-fmus"


def compiled_copy(path: Path, interface: Any, platforms: list[str]) -> Path:
    """The FMU with a binary for this platform compiled from its sources (cached by sha256).

    Args:
        path: the source-only .fmu.
        interface: its FmuInterface (sha256, model identifier).
        platforms: the platforms it has binaries for, for the message.
    Raises:
        FmuInterfaceError: CMake or the compiler is missing, or the build fails.
    """
    target = compile_cache_dir() / interface.sha256[:20] / path.name
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as work:
        unzipped, build = Path(work) / "fmu", Path(work) / "build"
        build.mkdir()
        with zipfile.ZipFile(path) as archive:
            archive.extractall(unzipped)
        problem = _build_binary(unzipped, build)
        if problem:
            has = f"binaries for {', '.join(platforms)}" if platforms else "no binary"
            raise FmuInterfaceError(f"{path}: no binary for this platform ({has}), and its C "
                                    f"sources cannot be compiled here: {problem}")
        partial = Path(work) / path.name
        shutil.make_archive(str(partial.with_suffix("")), "zip", unzipped)
        os.replace(partial.with_suffix(".zip"), target)
    return target


def _build_binary(unzipped: Path, build: Path) -> str | None:
    """Compile the FMU's sources into unzipped/binaries/; what went wrong, or None."""
    import fmpy
    from fmpy.build import create_cmake_settings

    if shutil.which("cmake") is None:
        return "cmake is not installed (fmpy builds FMU sources with CMake)"
    try:
        create_cmake_settings(unzipped, build)
    except Exception as exc:  # fmpy raises bare Exceptions for a missing build description
        return f"no usable build description ({exc})"
    c_code = Path(fmpy.__file__).parent / "c-code"
    for command in (["cmake", "-S", str(c_code), "-B", str(build)],
                    ["cmake", "--build", str(build), "--target", "install"]):
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            lines = [l for l in (done.stderr + done.stdout).splitlines() if "rror" in l]
            return (lines or ["the build failed"])[0].strip()
    return None
