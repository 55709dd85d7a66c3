"""Staged bundle writing: a new bundle replaces an old one whole, a failed export leaves the target as it was,
a folder that is not a bundle is refused."""

import pytest

from core.errors import InputError
from export.bundle import staged_bundle


def test_a_bundle_replaces_the_old_one_whole(tmp_path) -> None:
    out = tmp_path / "bundle"
    with staged_bundle(out) as folder:
        (folder / "bundle.json").write_text("{}")
        (folder / "old.onnx").write_text("old")
    with staged_bundle(out) as folder:
        (folder / "bundle.json").write_text("{}")
    assert sorted(p.name for p in out.iterdir()) == ["bundle.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle"]  # no staging folder left


def test_a_failed_export_leaves_the_target_alone(tmp_path) -> None:
    out = tmp_path / "bundle"
    with staged_bundle(out) as folder:
        (folder / "bundle.json").write_text("{}")
    with pytest.raises(RuntimeError), staged_bundle(out) as folder:
        (folder / "half.onnx").write_text("x")
        raise RuntimeError("export failed")
    assert sorted(p.name for p in out.iterdir()) == ["bundle.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle"]


def test_other_folders_are_refused(tmp_path) -> None:
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="is not a bundle folder"), staged_bundle(tmp_path / "data"):
        pass
    assert (tmp_path / "data" / "notes.txt").read_text() == "mine"
