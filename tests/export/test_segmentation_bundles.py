"""The VOS and DAVOS bundles, exported side by side (``export/pool.py``), hold every graph of their task, and
their exporters refuse a graph name outside it."""

import pytest

from core.errors import InputError
from export import davos_onnx, vos_onnx


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
