"""The packages form layers: ``core`` <- ``data`` <- ``models`` <- ``export`` / ``runtime`` <- ``bench`` / ``cli`` /
the two entry scripts, and no module imports a package above its own (every import statement, also inside
functions, is read with ``ast``). ``runtime`` (the deployment runtime) sits at the export level but stays
torch-free: it imports only the standard library, numpy, onnxruntime, OpenCV, itself and the torch-free modules of
``core``; ``export`` may use it to check the bundles it writes, ``models`` never."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Rank of each top-level package (a module may import packages of its own rank or below).
LAYERS = {"core": 0, "data": 1, "models": 2, "export": 3, "runtime": 3, "bench": 4, "cli": 4, "infer": 5,
          "train": 5}
#: Imports allowed between packages of the same rank: the ``demo`` command runs each benchmark's ``demo()``; an
#: export checks its bundle with the runtime that will run it.
PEER_IMPORTS = {("cli", "bench"), ("export", "runtime")}
#: Third-party packages the runtime may import (with the standard library).
RUNTIME_DEPENDENCIES = {"numpy", "onnxruntime", "cv2"}


def imported_modules(path: Path, root: Path = ROOT) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path`` (a file under ``root``), relative imports
    resolved."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = ".".join(path.relative_to(root).with_suffix("").parts[:-1])
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                name = ".".join([*base, node.module] if node.module else base)
            else:
                name = node.module or ""
            out.append((node.lineno, name))
    return out


def torch_free_core(root: Path = ROOT) -> set[str]:
    """``core.<name>`` modules whose imports, followed through ``core``, reach only the standard library and the
    runtime's dependencies (the ``core`` modules the runtime may use)."""
    imports = {f"core.{p.stem}" if p.stem != "__init__" else "core": {n for _, n in imported_modules(p, root)}
               for p in (root / "core").glob("*.py")} if (root / "core").is_dir() else {}
    free: set[str] = set()
    while True:
        new = {m for m, names in imports.items() if m not in free and all(
            n.split(".")[0] in sys.stdlib_module_names | RUNTIME_DEPENDENCIES or n in free or n in ("core", m)
            for n in names)}
        if not new:
            return free
        free |= new


def _runtime_may_import(name: str, free_core: set[str]) -> bool:
    top = name.split(".")[0]
    return top in sys.stdlib_module_names | RUNTIME_DEPENDENCIES | {"runtime"} or name in free_core


def layer_violations(root: Path = ROOT) -> list[str]:
    """``file:line: a -> b`` for every import of a higher layer, of a peer not allowed, or (in ``runtime``) of
    anything torch-based."""
    found = []
    free_core = torch_free_core(root)
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] in (".venv", "tests", "build", "outputs") or rel.parts[0].startswith("."):
            continue
        own = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        if own not in LAYERS:
            continue
        for line, name in imported_modules(path, root):
            top = name.split(".")[0]
            if own == "runtime":
                if not _runtime_may_import(name, free_core):
                    found.append(f"{rel}:{line}: {own} -> {name}")
                continue
            if top not in LAYERS or top == own:
                continue
            upward = LAYERS[top] > LAYERS[own]
            peer = LAYERS[top] == LAYERS[own] and (own, top) not in PEER_IMPORTS
            if upward or peer:
                found.append(f"{rel}:{line}: {own} -> {name}")
    return found


def test_no_import_runs_upwards() -> None:
    violations = layer_violations()
    assert not violations, ("imports against the layers core <- data <- models <- export/runtime <- bench/cli, or "
                            "of torch-based code in runtime:\n" + "\n".join(violations))


@pytest.mark.parametrize(("package", "statement"), [
    ("core", "from data.world.dem import Dem"),
    ("data", "import models.vos.tracker"),
    ("models", "from export.onnx import export_onnx"),
    ("models", "from runtime.vos import OnnxFRTMTracker"),
    ("export", "from bench.vos import parse_args"),
    ("bench", "from cli.report import print_report"),
    ("runtime", "import torch"),
    ("runtime", "from models.builders import frtm_tracker"),
    ("runtime", "from export.onnx import OPSET"),
    ("runtime", "from core.threads import cpu_threads"),  # a core module of no known torch-free file
])
def test_a_deliberate_upward_import_is_caught(tmp_path, package, statement) -> None:
    """The same walk over a copy of the layout with one bad import (inside a function, as lazy imports are)."""
    (tmp_path / package).mkdir()
    (tmp_path / package / "bad.py").write_text(f"def f():\n    {statement}\n")
    assert layer_violations(tmp_path) == [f"{package}/bad.py:2: {package} -> {statement.split()[1]}"]


def test_core_modules_the_runtime_uses_are_torch_free() -> None:
    """The runtime's ``core`` imports are torch-free (``core.threads`` and the geometry, which import torch, are
    not), and ``core.errors`` and ``core/__init__`` import nothing at all."""
    free = torch_free_core()
    used = {n for p in (ROOT / "runtime").glob("*.py") for _, n in imported_modules(p) if n.startswith("core")}
    assert used and used <= free
    assert not {"core.threads", "core.cylinder", "core.raycast"} & free
    for name in ("__init__.py", "errors.py"):
        assert {n for _, n in imported_modules(ROOT / "core" / name)} <= {"__future__"}, name
