"""The compiled parts load without scipy.linalg (controllers.jit._load_numpy_support_without_scipy_linalg),
and numba in that process answers as it would have: the BLAS flag it sets on a working scipy, np.dot
and np.correlate compiled afterwards giving the bits of a process that loaded numba its own way.

Each case runs in a fresh interpreter: which modules are loaded is process-wide state."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("numba")
pytest.importorskip("scipy.linalg")  # without scipy there is nothing to leave out

ROOT = Path(__file__).resolve().parents[2]

# After the first compiled part (or numba's own first compile), compile np.dot and np.correlate
# in the same process and report what is loaded, the flag and the results' bits.
PROBE = """
import json, sys
import numpy as np
{load}
after_load = "scipy.linalg" in sys.modules
import numba
import numba.np.arraymath as arraymath
flag = arraymath._HAVE_BLAS

@numba.njit
def dot(a, b):
    return np.dot(a, b)

@numba.njit
def correlate(a, b):
    return np.correlate(a, b)

a = np.linspace(0.1, 3.7, 41)
b = np.sin(np.arange(41.0)) / 7.0
print(json.dumps({{"linalg_after_load": after_load, "blas": flag, "dot": float(dot(a, b)).hex(),
                   "correlate": [float(x).hex() for x in correlate(a, b[:9])]}}))
"""

OURS = """
import os
os.environ["COSIM_JIT"] = "on"
from controllers.backstepping import step_path
assert step_path.compiled_step() is not None
import sys
assert "numba.np.arraymath" in sys.modules  # loaded by the step's load, through the detour
"""

NUMBAS_OWN = """
import numba
@numba.njit
def warm(x):
    return x + 1.0
warm(1.0)
"""


def probe(load: str) -> dict:
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", PROBE.format(load=load)], cwd=ROOT, env=environment,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_the_compiled_step_loads_without_scipy_linalg_and_numba_answers_as_without_the_detour():
    ours, own = probe(OURS), probe(NUMBAS_OWN)
    assert ours["linalg_after_load"] is False
    assert own["linalg_after_load"] is True  # what numba's own first compile costs
    assert ours["blas"] is own["blas"] is True
    assert ours["dot"] == own["dot"]
    assert ours["correlate"] == own["correlate"]


def test_nothing_is_changed_when_scipy_linalg_is_loaded_first():
    ours = probe("import scipy.linalg\n" + OURS)
    assert ours["linalg_after_load"] is True
    assert ours["blas"] is True


def test_a_process_whose_scipy_linalg_is_missing_gets_the_flag_off(tmp_path):
    # a scipy.linalg that cannot be found: numba would find no BLAS, and neither do we
    blocker = tmp_path / "sitecustomize.py"
    blocker.write_text("import importlib.abc, sys\n"
                       "class Hide(importlib.abc.MetaPathFinder):\n"
                       "    def find_spec(self, name, path, target=None):\n"
                       "        if name == 'scipy.linalg' or name.startswith('scipy.linalg.'):\n"
                       "            raise ModuleNotFoundError(name)\n"
                       "sys.meta_path.insert(0, Hide())\n")
    environment = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}"}
    script = OURS + "import numba.np.arraymath as a\nprint(a._HAVE_BLAS)\n"
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=environment,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "False"


def test_the_hiding_finder_hides_the_package_from_its_own_thread_only():
    import threading

    from controllers.jit import _HiddenOnThisThread

    hidden = _HiddenOnThisThread("scipy.linalg")
    with pytest.raises(ModuleNotFoundError):
        hidden.find_spec("scipy.linalg")
    with pytest.raises(ModuleNotFoundError):
        hidden.find_spec("scipy.linalg.cython_blas")
    assert hidden.find_spec("scipy.linalgebra") is None and hidden.find_spec("scipy") is None
    seen = []
    other = threading.Thread(target=lambda: seen.append(hidden.find_spec("scipy.linalg")))
    other.start()
    other.join()
    assert seen == [None]  # another thread goes on to the next finders
