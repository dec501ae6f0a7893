"""Build the built-in plant FMUs (FMI 2.0 and 3.0 co-simulation) from C sources.

Each model folder under ``fmus/`` (a folder holding ``variables.def``) is
compiled with the shared framework in ``fmus/framework/``. The
modelDescription.xml files come from a small generator program compiled with
the model's code (``xmlgen.c``), so the variable table is read by the compiler
only. Each FMU carries its C sources (FMI2 ``<SourceFiles>``, FMI3
``sources/buildDescription.xml``) so another platform can rebuild it.

Public API: ``MODELS``, ``FmuBuildError``, ``build_fmu``, ``build_all``,
``ensure_fmu``, ``fmu_file_name``, ``build_fmu_from`` (a model folder outside
fmus/, for tests and benchmarks). Runs take the built-in FMUs from the per-user
cache of `cosim.fmu.cache` instead (keyed by source hash and compiler).
"""
from __future__ import annotations

import os
import platform
import shutil
import subprocess
import tempfile
import threading
import zipfile
from pathlib import Path

from cosim.errors import UserError

from cosim.resources import CHECKOUT_DIR, builtin_models, fmus_dir

FMUS_DIR = fmus_dir()  # the checkout's fmus/, or the copy an installed wheel carries
FRAMEWORK_DIR = FMUS_DIR / "framework"
CHECKOUT_OUT_DIR = CHECKOUT_DIR / "build" / "fmus"  # `cosim build-fmus` in a checkout

CFLAGS = ["-std=c99", "-O2", "-fPIC", "-fvisibility=hidden",
          "-Wall", "-Wextra", "-Wpedantic", "-Werror"]
RUNTIME_SOURCES = ["runtime.c"]
GENERATOR_SOURCE = "xmlgen.c"
ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed, so the same sources give the same .fmu bytes


class FmuBuildError(UserError):
    """The FMU could not be built; the message names the model and the cause.

    A UserError, so `cosim build-fmus` / `cosim run` print it without a traceback.
    """


def find_models() -> list[str]:
    """The built-in models: the folders of fmus/ holding a variables.def."""
    return builtin_models()


MODELS: list[str] = find_models()


def fmi_include_dir() -> Path:
    """Directory of the FMI 2.0/3.0 headers shipped by the installed fmpy."""
    import fmpy

    path = Path(fmpy.__file__).resolve().parent / "c-code"
    if not (path / "fmi3Functions.h").is_file():
        raise FmuBuildError(f"FMI headers not found in {path} (is fmpy installed?)")
    return path


def fmu_file_name(model: str, fmi_version: int) -> str:
    """File name of a built-in FMU: ``Model.fmu`` (FMI 2.0) or ``Model-fmi3.fmu``.

    Args:
        model: model folder name under fmus/, e.g. "Bicycle".
        fmi_version: 2 or 3.
    """
    return f"{model}.fmu" if fmi_version == 2 else f"{model}-fmi3.fmu"


def _platform_dir(fmi_version: int) -> str:
    machine = platform.machine().lower()
    if platform.system() != "Linux" or machine not in ("x86_64", "amd64", "aarch64"):
        raise FmuBuildError(f"building FMUs is supported on Linux x86_64/aarch64, "
                            f"not {platform.system()} {machine}")
    if fmi_version == 2:
        return "linux64"
    return ("x86_64" if machine in ("x86_64", "amd64") else "aarch64") + "-linux"


def model_sources(model_dir: Path) -> list[Path]:
    """All files that go into a model's FMU (framework + model folder), sorted.

    Args:
        model_dir: the model folder (holding variables.def and model.c).
    """
    model = model_dir.name
    files = [p for p in FRAMEWORK_DIR.iterdir()
             if p.suffix in (".c", ".h") and p.name != GENERATOR_SOURCE]
    files += [p for p in model_dir.iterdir()
              if p.suffix in (".c", ".h", ".def") and p.is_file()]
    names = [p.name for p in files]
    clashes = sorted({n for n in names if names.count(n) > 1})
    if clashes:
        raise FmuBuildError(f"{model}: file names clash with the framework: {clashes}")
    return sorted(files, key=lambda p: p.name)


def _c_files(model_dir: Path, fmi_version: int) -> list[Path]:
    api = FRAMEWORK_DIR / f"fmi{fmi_version}_api.c"
    runtime = [FRAMEWORK_DIR / n for n in RUNTIME_SOURCES]
    return [api, *runtime, *sorted(model_dir.glob("*.c"))]


def _run_gcc(args: list[str], what: str) -> None:
    gcc = shutil.which("gcc")
    if gcc is None:
        raise FmuBuildError(f"{what}: gcc not found on PATH")
    proc = subprocess.run([gcc, *args], capture_output=True, text=True)
    if proc.returncode != 0:
        raise FmuBuildError(f"{what}: gcc failed (exit {proc.returncode}):\n"
                            f"{proc.stderr.strip()}")


def _includes(model_dir: Path) -> list[str]:
    return [f"-I{FRAMEWORK_DIR}", f"-I{model_dir}", f"-I{fmi_include_dir()}"]


def generate_model_description(model_dir: Path, fmi_version: int, work_dir: Path) -> str:
    """Compile the XML generator with the model's code and return its output.

    Args:
        model_dir: the model folder (holding variables.def and model.c).
        fmi_version: 2 or 3.
        work_dir: scratch folder for the generator executable.
    """
    model = model_dir.name
    exe = work_dir / "xmlgen"
    model_c = [str(p) for p in sorted(model_dir.glob("*.c"))]
    srcs = [str(FRAMEWORK_DIR / GENERATOR_SOURCE),
            *(str(FRAMEWORK_DIR / n) for n in RUNTIME_SOURCES), *model_c]
    _run_gcc([*CFLAGS, *_includes(model_dir), *srcs, "-lm", "-o", str(exe)],
             f"{model}: compiling the modelDescription generator")
    source_names = [p.name for p in _c_files(model_dir, fmi_version)]
    proc = subprocess.run([str(exe), str(fmi_version), *source_names],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise FmuBuildError(f"{model}: variable table rejected by the generator:\n"
                            f"{proc.stderr.strip()}")
    return proc.stdout


def _build_description(model_dir: Path, fmi_version: int) -> str:
    model = model_dir.name
    files = "\n".join(f'      <SourceFile name="{p.name}"/>'
                      for p in _c_files(model_dir, fmi_version))
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            '<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{model}">\n'
            '    <SourceFileSet language="C99">\n'
            f'{files}\n'
            f'      <PreprocessorDefinition name="MODEL_IDENTIFIER" value="{model}"/>\n'
            '    </SourceFileSet>\n'
            '    <Library name="m"/>\n'
            '  </BuildConfiguration>\n'
            '</fmiBuildDescription>\n')


def _zip_add(zf: zipfile.ZipFile, name: str, data: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    zf.writestr(info, data)


def _write_fmu(path: Path, entries: dict[str, bytes]) -> None:
    """Write the zip atomically (temp file + rename), entries in sorted order."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # not mkstemp: its 0600 mode would survive the rename; the umask applies here
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        with zipfile.ZipFile(tmp, "w") as zf:
            for name in sorted(entries):
                _zip_add(zf, name, entries[name])
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def build_fmu(model: str, fmi_version: int, out_dir: Path) -> Path:
    """Compile one built-in model into a co-simulation FMU and return the .fmu path.

    Args:
        model: model folder name under fmus/ (one of MODELS), e.g. "Bicycle".
        fmi_version: 2 (writes <model>.fmu) or 3 (writes <model>-fmi3.fmu).
        out_dir: folder for the .fmu (created if missing).
    Raises:
        FmuBuildError: unknown model/version, compiler error (with gcc's
            message) or a variable table the generator rejects.
    """
    if model not in find_models():
        raise FmuBuildError(f"unknown model {model!r}: no {FMUS_DIR / model / 'variables.def'}"
                            f" (models: {', '.join(find_models()) or 'none'})")
    return build_fmu_from(FMUS_DIR / model, fmi_version, out_dir)


def build_fmu_from(model_dir: Path, fmi_version: int, out_dir: Path) -> Path:
    """Compile a model folder anywhere (e.g. a test or benchmark model) with the framework.

    Args:
        model_dir: folder holding variables.def and model.c; its name is the
            model identifier.
        fmi_version: 2 or 3.
        out_dir: folder for the .fmu (created if missing).
    Raises:
        FmuBuildError: as build_fmu.
    """
    model_dir = Path(model_dir)
    model = model_dir.name
    if fmi_version not in (2, 3):
        raise FmuBuildError(f"{model}: fmi_version must be 2 or 3, not {fmi_version!r}")
    if not (model_dir / "variables.def").is_file():
        raise FmuBuildError(f"{model}: no variables.def in {model_dir}")
    sources = model_sources(model_dir)
    with tempfile.TemporaryDirectory(prefix=f"fmu-{model}-") as tmp:
        work = Path(tmp)
        xml = generate_model_description(model_dir, fmi_version, work)
        lib = work / f"{model}.so"
        _run_gcc([*CFLAGS, "-shared", f"-DMODEL_IDENTIFIER={model}", *_includes(model_dir),
                  *(str(p) for p in _c_files(model_dir, fmi_version)), "-lm", "-o", str(lib)],
                 f"{model}: compiling the FMI {fmi_version}.0 binary")
        entries = {"modelDescription.xml": xml.encode(),
                   f"binaries/{_platform_dir(fmi_version)}/{model}.so": lib.read_bytes()}
    for src in sources:
        entries[f"sources/{src.name}"] = src.read_bytes()
    if fmi_version == 3:
        entries["sources/buildDescription.xml"] = _build_description(model_dir, 3).encode()
    readme = model_dir / "README.md"
    if readme.is_file():
        entries["documentation/README.md"] = readme.read_bytes()
    out = Path(out_dir) / fmu_file_name(model, fmi_version)
    _write_fmu(out, entries)
    return out


def build_all(out_dir: Path | None = None) -> list[Path]:
    """Build every model of MODELS as FMI 2.0 and FMI 3.0 FMUs.

    Args:
        out_dir: output folder; default <checkout>/build/fmus (`cosim.fmu.cache` for runs).
    Returns:
        the .fmu paths, per model the FMI 2.0 one then the FMI 3.0 one.
    Raises:
        FmuBuildError: no model sources found (no fmus/ folder with a variables.def).
    """
    models = find_models()
    if not models:
        raise FmuBuildError(f"no built-in model sources found in {FMUS_DIR} (a model is a "
                            "folder there holding a variables.def; is the package complete?)")
    out = Path(out_dir) if out_dir is not None else CHECKOUT_OUT_DIR
    return [build_fmu(m, v, out) for m in models for v in (2, 3)]


def parse_fmu_name(name: str) -> tuple[str, int]:
    """(model, FMI version) of a built-in FMU name: "Bicycle-fmi3.fmu" -> ("Bicycle", 3)."""
    stem = name[:-4] if name.endswith(".fmu") else name
    if stem.endswith("-fmi3"):
        return stem[:-5], 3
    return stem, 2


def ensure_fmu(name: str, out_dir: Path | None = None) -> Path:
    """Return a built-in FMU, building it when missing or older than its sources.

    Args:
        name: "Bicycle", "Bicycle-fmi3" (with or without ".fmu"), etc.
        out_dir: output folder; default <checkout>/build/fmus (`cosim.fmu.cache` for runs).
    Raises:
        FmuBuildError: unknown name or a failed build.
    """
    model, version = parse_fmu_name(name)
    if model not in find_models():
        raise FmuBuildError(f"{name!r} is not a built-in FMU (built-in models: "
                            f"{', '.join(find_models()) or 'none'}; FMI 3.0 ones end in -fmi3)")
    out = Path(out_dir) if out_dir is not None else CHECKOUT_OUT_DIR
    path = out / fmu_file_name(model, version)
    inputs = [*model_sources(FMUS_DIR / model), FMUS_DIR / model / "README.md",
              FRAMEWORK_DIR / GENERATOR_SOURCE, Path(__file__)]
    newest = max(p.stat().st_mtime for p in inputs if p.exists())
    if path.is_file() and path.stat().st_mtime >= newest:
        return path
    return build_fmu(model, version, out)
