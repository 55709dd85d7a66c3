"""The tests mirror the package one to one: ``tests/<path>/test_<name>.py`` tests the module ``<path>/<name>.py``
(``test_init.py`` tests ``<path>/__init__.py``); besides them only the project-wide tests (``PROJECT_WIDE``) sit
at the top of ``tests/``."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Tests of the project as a whole rather than of one module.
PROJECT_WIDE = {"test_layers.py", "test_mirror.py", "test_bad_input.py"}


def misplaced_tests(root: Path = ROOT) -> list[str]:
    """``tests/... (no module ...)`` for every test file under ``root / "tests"`` whose module is missing."""
    found = []
    tests = root / "tests"
    for path in sorted(tests.rglob("test_*.py")):
        rel = path.relative_to(tests)
        if len(rel.parts) == 1 and rel.name in PROJECT_WIDE:
            continue
        stem = rel.stem.removeprefix("test_")
        module = Path(*rel.parts[:-1], "__init__.py" if stem == "init" else f"{stem}.py")
        if not (root / module).is_file():
            found.append(f"tests/{rel.as_posix()} (no module {module.as_posix()})")
    return found


def test_every_test_file_names_an_existing_module() -> None:
    misplaced = misplaced_tests()
    assert not misplaced, "test files that mirror no module:\n" + "\n".join(misplaced)


@pytest.mark.parametrize(("test_file", "missing"), [
    ("tests/data/sfm/test_bundler.py", None),
    ("tests/cli/test_init.py", None),
    ("tests/test_infer.py", None),  # a top-level module: infer.py
    ("tests/test_layers.py", None),  # project-wide
    ("tests/data/sfm/test_sfm_readers.py", "data/sfm/sfm_readers.py"),  # named after no module
    ("tests/models/test_bundler.py", "models/bundler.py"),  # a module of another package
    ("tests/test_bundler.py", "bundler.py"),  # a package module tested at the top level
    ("tests/models/test_init.py", "models/__init__.py"),  # models/ of the made-up layout has no __init__.py
])
def test_a_misplaced_test_file_is_caught(tmp_path, test_file, missing) -> None:
    """The same walk over a made-up layout holding one test file (and a conftest.py, which is no test file)."""
    for module in ("data/sfm/bundler.py", "data/sfm/__init__.py", "cli/__init__.py", "models/builders.py",
                   "infer.py"):
        (tmp_path / module).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / module).write_text("")
    (tmp_path / test_file).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / test_file).write_text("")
    (tmp_path / "tests" / "conftest.py").write_text("")
    expected = [] if missing is None else [f"{test_file} (no module {missing})"]
    assert misplaced_tests(tmp_path) == expected
