"""Build hook: put the FMU C sources and the shipped scenarios into the wheel.

The repository keeps them in its top-level folders `fmus/` and `scenarios/`;
a wheel carries copies under `cosim/_data/`, found at run time by
`cosim.resources`. An editable install copies nothing: it reads the
checkout's folders directly. Everything else is in pyproject.toml.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
# folder -> file patterns that go into the wheel
DATA = {"fmus": ("*.c", "*.h", "*.def", "*.md"),
        "scenarios": ("*.yaml", "*.yml", "*.csv", "*.json", "*.md")}


class BuildPyWithData(build_py):
    """build_py, then copy the data folders into <build_lib>/cosim/_data/."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        target = Path(self.build_lib) / "cosim" / "_data"
        shutil.rmtree(target, ignore_errors=True)  # no stale file from an earlier build
        for folder, patterns in DATA.items():
            for pattern in patterns:
                for source in (ROOT / folder).rglob(pattern):
                    if "figures" in source.relative_to(ROOT / folder).parts:
                        continue  # documentation images, not data
                    dest = target / source.relative_to(ROOT)
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(source, dest)


setup(cmdclass={"build_py": BuildPyWithData})
