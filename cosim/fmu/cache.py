"""The per-user cache of built-in FMUs: compiled on first use, never into site-packages.

A run that names a built-in FMU (`fmu: Vehicle8DOF`) gets it from
`<cache>/fmus/<Model>-<key>/`, where the key is a hash of everything that
decides the binary: the model's and the framework's sources, the build module,
the compiler flags, the compiler itself (its resolved path, size and mtime, so
an upgraded gcc gives a new key), the fmpy FMI headers and the machine. The
same sources and compiler therefore always give the same, already built FMU;
an edit gives a fresh build beside the old one. Builds write atomically
(`cosim.fmu.build`), so concurrent runs may race to build the same key safely.

`<cache>` is `$COSIM_CACHE_DIR` when set, else platformdirs' user cache
folder for "cosim" (`~/.cache/cosim` on Linux).
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
import shutil
from pathlib import Path

from cosim.fmu import build
from cosim.fmu.build import FmuBuildError

CACHE_ENV = "COSIM_CACHE_DIR"
KEY_CHARS = 16


def cache_root() -> Path:
    """The cache folder: $COSIM_CACHE_DIR, else the user cache folder of "cosim"."""
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override)
    import platformdirs

    return Path(platformdirs.user_cache_dir("cosim", appauthor=False))


@functools.lru_cache(maxsize=None)
def _compiler_identity(gcc: str | None) -> str:
    if gcc is None:
        return "no-gcc"
    real = os.path.realpath(gcc)
    info = os.stat(real)
    return f"{real}:{info.st_size}:{info.st_mtime_ns}"


def compiler_identity() -> str:
    """The gcc that builds the FMUs, as "resolved path:size:mtime" ("no-gcc" when absent)."""
    return _compiler_identity(shutil.which("gcc"))


def source_key(model: str) -> str:
    """The cache key of a built-in model: a hash of its sources, the build and the compiler.

    Args:
        model: a built-in model name (a folder of fmus/).
    """
    model_dir = build.FMUS_DIR / model
    digest = hashlib.sha256()
    files = [*build.model_sources(model_dir), model_dir / "README.md",
             build.FRAMEWORK_DIR / build.GENERATOR_SOURCE, Path(build.__file__)]
    headers = sorted((build.fmi_include_dir()).glob("fmi*.h"))
    for path in files + headers:
        if path.is_file():
            digest.update(f"{path.name}\0{path.stat().st_size}\0".encode())
            digest.update(path.read_bytes())
    for part in (*build.CFLAGS, compiler_identity(), platform.machine()):
        digest.update(f"{part}\0".encode())
    return digest.hexdigest()[:KEY_CHARS]


def builtin_fmu(name: str) -> Path:
    """The built-in FMU `name` from the cache, built there first if it is not yet.

    Args:
        name: "Bicycle", "Vehicle8DOF-fmi3" (with or without ".fmu"), ...
    Raises:
        FmuBuildError: an unknown name, a failed build, or a cache folder that cannot be written.
    """
    model, version = build.parse_fmu_name(name)
    models = build.find_models()
    if model not in models:
        raise FmuBuildError(f"{name!r} is not a built-in FMU (built-in models: "
                            f"{', '.join(models) or 'none'}; FMI 3.0 ones end in -fmi3)")
    folder = cache_root() / "fmus" / f"{model}-{source_key(model)}"
    path = folder / build.fmu_file_name(model, version)
    if path.is_file():
        return path
    try:
        return build.build_fmu(model, version, folder)
    except OSError as exc:
        raise FmuBuildError(f"{model}: cannot write the FMU cache {folder}: "
                            f"{exc.strerror or exc} (set {CACHE_ENV} to another folder)") from None


def build_all_cached() -> list[Path]:
    """Every built-in model as FMI 2.0 and 3.0 FMUs in the cache (what runs use).

    Raises:
        FmuBuildError: no model sources found, or a failed build.
    """
    models = build.find_models()
    if not models:
        build.build_all()  # raises the "no model sources" error
    return [builtin_fmu(f"{m}{suffix}") for m in models for suffix in ("", "-fmi3")]
