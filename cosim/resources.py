"""Where the platform's own files are: the FMU C sources and the shipped scenarios.

In a checkout (an editable install) they are the repository's top-level
folders `fmus/` and `scenarios/`. A wheel (`pip install .`, `pip install
dist/*.whl`) carries copies of them as package data under `cosim/_data/`
(copied there at build time by `setup.py`); that copy wins when present.

Built-in models are discovered here, not listed: every folder under `fmus/`
holding a `variables.def` is one (`fmus/README.md`), built as FMI 2.0
(`Model`) and FMI 3.0 (`Model-fmi3`). Standard library only, so every layer
may import it.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
DATA_DIR = PACKAGE_DIR / "_data"  # only in an installed wheel
CHECKOUT_DIR = PACKAGE_DIR.parent  # the repository root in a checkout
FMI3_SUFFIX = "-fmi3"


def _resource(name: str) -> Path:
    packaged = DATA_DIR / name
    return packaged if packaged.is_dir() else CHECKOUT_DIR / name


def fmus_dir() -> Path:
    """The folder of the FMU C sources: `framework/` and one folder per model."""
    return _resource("fmus")


def scenarios_dir() -> Path:
    """The folder of the shipped scenario YAML files and the data they use."""
    return _resource("scenarios")


def is_checkout() -> bool:
    """True when running from a source checkout (its `fmus/` beside the package, no wheel data)."""
    return not DATA_DIR.is_dir() and (CHECKOUT_DIR / "fmus").is_dir() \
        and (CHECKOUT_DIR / "pyproject.toml").is_file()


def builtin_models() -> list[str]:
    """The built-in model names: folders of `fmus/` holding a `variables.def`, sorted."""
    root = fmus_dir()
    if not root.is_dir():
        return []
    return sorted(p.name for p in root.iterdir()
                  if p.is_dir() and (p / "variables.def").is_file())


def builtin_fmu_names() -> tuple[str, ...]:
    """Every name a scenario's `fmu:` may give a built-in FMU: each model, then its `-fmi3` form."""
    models = builtin_models()
    return (*models, *(m + FMI3_SUFFIX for m in models))
