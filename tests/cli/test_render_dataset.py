"""``infer.py render-dataset``: a killed render resumes to the same bytes; a folder of other settings is refused."""

import json

import pytest

from infer import main
from tests.cli.conftest import kill_and_resume, run_infer, tree_bytes

ARGS = ["render-dataset", "--count", "10", "--width", "256", "--height", "32", "--dem-size", "3000",
        "--dem-cell", "10", "--batch", "2"]


@pytest.mark.slow
def test_killed_render_resumes_to_the_same_files(tmp_path) -> None:
    run_infer([*ARGS, "--out", str(tmp_path / "whole")])
    hit = kill_and_resume([*ARGS, "--out", str(tmp_path / "killed")], tmp_path / "killed", kills=3, seed=0)
    assert hit == 3
    whole = tree_bytes(tmp_path / "whole")
    assert len(whole) == 10 + 4 and tree_bytes(tmp_path / "killed") == whole


def test_finished_folder_is_kept_and_other_settings_are_refused(tmp_path, capsys) -> None:
    out = tmp_path / "data"
    (out).mkdir()
    (out / "meta.json").write_text(json.dumps({"count": 3, "settings": {"count": 3}}))
    assert main([*ARGS, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already holds a horizon dataset with other settings" in err[0]
    assert sorted(p.name for p in out.iterdir()) == ["meta.json"]
