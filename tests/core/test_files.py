"""Atomic output files: a completed write replaces the target, a failed one leaves nothing, and a resumed job
removes the temporary files a killed writer left behind (hidden ``.STEM.PID.partial.SUFFIX`` names) and
nothing else; staging folders of dead writers are removed, those of running ones kept."""

import os

import pytest

from core.files import atomic_path, partial_name, remove_partials, staging_folder, write_text


def test_failed_write_leaves_nothing(tmp_path) -> None:
    target = tmp_path / "a.txt"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed")
    assert list(tmp_path.iterdir()) == []
    write_text(target, "whole")
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"] and target.read_text() == "whole"


def test_remove_partials_removes_only_stale_temporaries(tmp_path) -> None:
    stale = [tmp_path / ".00001.4560.partial.png", tmp_path / ".scores.77.partial.json"]
    for path in stale:
        path.write_bytes(b"")
    keep = [tmp_path / "00001.png", tmp_path / ".hidden", tmp_path / "partial.png"]
    for path in keep:
        path.write_bytes(b"x")
    (tmp_path / ".dir.partial").mkdir()  # a folder is not a writer's temporary file
    assert partial_name(tmp_path / "00001.png").name.startswith(".00001.") and partial_name(
        tmp_path / "00001.png").name.endswith(".partial.png")
    remove_partials(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*(p.name for p in keep), ".dir.partial"])
    remove_partials(tmp_path / "missing")  # a folder not written yet: nothing to do


def test_staging_folder_removes_only_folders_of_dead_writers(tmp_path) -> None:
    import subprocess
    import sys

    out = tmp_path / "out"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".out.{int(dead.stdout)}.partial"  # a writer killed mid-run
    live = tmp_path / f".out.{os.getppid()}.partial"  # a writer still running
    other = tmp_path / f".other.{int(dead.stdout)}.partial"  # another folder's
    for folder in (stale, live, other):
        folder.mkdir()
        (folder / "00000.png").write_bytes(b"x")
    staging = staging_folder(out)
    assert staging == tmp_path / f".out.{os.getpid()}.partial" and staging.is_dir() and not any(staging.iterdir())
    assert not stale.exists() and live.exists() and other.exists()
