"""Running the runtime's commands in a subprocess in which torch (and torchvision, Lightning, kornia) cannot be
imported: a meta-path finder installed before the command module runs refuses them. With ``RUNTIME_PYTHON`` set
to the interpreter of a venv that holds only ``.[runtime]`` (no torch at all), the commands run there instead:
``RUNTIME_PYTHON=/path/to/venv/bin/python pytest tests/runtime``."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Installs the blocking finder, then runs ``sys.argv[1]`` as ``python -m`` would, with the remaining arguments.
TORCH_FREE = """
import runpy, sys

class TorchBlocker:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("torch", "torchvision", "lightning", "kornia"):
            raise ImportError(f"{name} is blocked: the runtime must run without torch")
        return None

sys.meta_path.insert(0, TorchBlocker())
module, sys.argv = sys.argv[1], sys.argv[1:]
runpy.run_module(module, run_name="__main__", alter_sys=True)
"""


def run_torch_free(module: str, *args) -> subprocess.CompletedProcess:
    """``python -m module args`` with torch blocked, from the repository root, one thread, by ``RUNTIME_PYTHON``
    (default: this interpreter)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    python = os.environ.get("RUNTIME_PYTHON", sys.executable)
    return subprocess.run([python, "-c", TORCH_FREE, module, *map(str, args)], cwd=ROOT, env=env,
                          capture_output=True, text=True)


@pytest.fixture
def torch_free():
    """``torch_free(module, *args)``: run a runtime command without torch; asserts exit code 0."""

    def run(module: str, *args) -> subprocess.CompletedProcess:
        proc = run_torch_free(module, *args)
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc

    return run
