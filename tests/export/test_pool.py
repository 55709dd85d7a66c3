"""The export pool: jobs run in this process or in worker processes, each reported once; errors reach the caller;
the VOS and DAVOS bundles it exports hold every graph of their task."""

import os
from pathlib import Path

import pytest

from core.errors import InputError
from export import davos_onnx, vos_onnx
from export.pool import GraphJob, export_jobs


def write_pid(path: Path) -> None:
    """A job: write the id of the process that runs it."""
    path.write_text(str(os.getpid()))


def fail(path: Path) -> None:
    """A job that fails as an export does on bad input."""
    raise InputError(f"cannot export {path.name}")


@pytest.mark.parametrize("workers", [1, 2])
def test_every_job_runs_once_and_is_reported(tmp_path, capsys, workers) -> None:
    jobs = [GraphJob(f"g{i}.onnx", write_pid, (tmp_path / f"g{i}.onnx",)) for i in range(3)]
    export_jobs("export.test", jobs, workers)
    pids = {int((tmp_path / f"g{i}.onnx").read_text()) for i in range(3)}
    if workers == 1:
        assert pids == {os.getpid()}
    else:  # worker processes, not this one
        assert os.getpid() not in pids and 1 <= len(pids) <= 2
    lines = capsys.readouterr().err.splitlines()
    assert sorted(line.split()[1] for line in lines) == ["g0.onnx", "g1.onnx", "g2.onnx"]
    assert all(line.startswith("export.test: ") and line.endswith("/3)") for line in lines)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failed_job_raises_its_error(tmp_path, capsys, workers) -> None:
    with pytest.raises(InputError, match="cannot export bad.onnx"):
        export_jobs("export.test", [GraphJob("bad.onnx", fail, (tmp_path / "bad.onnx",))], workers)
    assert "exported" not in capsys.readouterr().err


@pytest.mark.parametrize("workers", [0, -1, 1.5])
def test_workers_must_be_a_positive_count(workers) -> None:
    with pytest.raises(InputError, match="--workers must be at least 1"):
        export_jobs("export.test", [GraphJob("g.onnx", write_pid, (Path("unused"),))], workers)


@pytest.mark.parametrize(("exporter", "fixture", "task"), [(vos_onnx, "vos_setup", "VOS"),
                                                          (davos_onnx, "davos_setup", "DAVOS")])
def test_the_bundle_holds_every_graph_and_names_are_checked(exporter, fixture: str, task: str, request,
                                                            tmp_path) -> None:
    """The parallel export (the fixtures' default: one worker per core) wrote each of GRAPHS; a name outside them
    is an InputError that writes nothing."""
    setup = request.getfixturevalue(fixture)
    assert {f"{name}.onnx" for name in exporter.GRAPHS} == {p.name for p in setup["bundle"].glob("*.onnx")}
    with pytest.raises(InputError, match=f"unknown {task} graph 'decoder'"):
        exporter.export_graph("decoder", setup["tracker"], tmp_path, 64, 96)
    assert list(tmp_path.iterdir()) == []
