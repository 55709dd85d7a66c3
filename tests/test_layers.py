"""The packages form layers: ``core`` <- ``data`` <- ``models`` <- ``export`` <- ``bench`` / ``cli`` / the two
entry scripts, and no module imports a package above its own (every import statement, also inside functions, is
read with ``ast``). ``runtime`` (when present) imports no torch at all."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Rank of each top-level package (a module may import packages of its own rank or below).
LAYERS = {"core": 0, "data": 1, "models": 2, "export": 3, "bench": 4, "cli": 4, "infer": 5, "train": 5}
#: Imports allowed between packages of the same rank: the ``demo`` command runs each benchmark's ``demo()``.
PEER_IMPORTS = {("cli", "bench")}
TORCH_FREE = ("runtime",)


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


def layer_violations(root: Path = ROOT) -> list[str]:
    """``file:line: a -> b`` for every import of a higher layer (or of a peer not allowed)."""
    found = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] in (".venv", "tests", "build", "outputs") or rel.parts[0].startswith("."):
            continue
        own = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        if own not in LAYERS and own not in TORCH_FREE:
            continue
        for line, name in imported_modules(path, root):
            top = name.split(".")[0]
            if own in TORCH_FREE:
                if top in ("torch", "torchvision", "lightning", "kornia") or (top in LAYERS and top != "core"):
                    found.append(f"{rel}:{line}: {own} -> {name} (runtime stays torch-free)")
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
    assert not violations, "imports against the layers core <- data <- models <- export <- bench/cli:\n" + "\n".join(
        violations)


@pytest.mark.parametrize(("package", "statement"), [
    ("core", "from data.world.dem import Dem"),
    ("data", "import models.vos.tracker"),
    ("models", "from export.onnx import export_onnx"),
    ("export", "from bench.vos import parse_args"),
    ("bench", "from cli.report import print_report"),
])
def test_a_deliberate_upward_import_is_caught(tmp_path, package, statement) -> None:
    """The same walk over a copy of the layout with one bad import (inside a function, as lazy imports are)."""
    (tmp_path / package).mkdir()
    (tmp_path / package / "bad.py").write_text(f"def f():\n    {statement}\n")
    assert layer_violations(tmp_path) == [f"{package}/bad.py:2: {package} -> {statement.split()[1]}"]


def test_the_core_error_type_imports_without_torch() -> None:
    """``core.errors`` (and ``core/__init__``) import nothing, so a torch-free runtime can share the error type."""
    for name in ("__init__.py", "errors.py"):
        assert {n for _, n in imported_modules(ROOT / "core" / name)} <= {"__future__"}, name
