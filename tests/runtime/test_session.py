"""onnxruntime sessions: inputs a graph rejects, missing and corrupt graphs, execution providers, each an
InputError naming the graph or the provider."""

import numpy as np
import pytest

from core.errors import InputError
from runtime.session import Graph, session_providers


def test_providers_fall_back_to_the_cpu() -> None:
    assert session_providers("cpu") == ["CPUExecutionProvider"]
    with pytest.raises(InputError, match="must be one of"):
        session_providers("npu")


def test_missing_and_corrupt_graphs(tmp_path) -> None:
    with pytest.raises(InputError, match="not found"):
        Graph(tmp_path / "missing.onnx")
    (tmp_path / "bad.onnx").write_bytes(b"not a graph")
    with pytest.raises(InputError, match="bad.onnx is not a readable ONNX graph"):
        Graph(tmp_path / "bad.onnx")


@pytest.mark.slow  # uses an exported bundle
def test_rejected_inputs_are_named(triangulation_bundle) -> None:
    graph = Graph(triangulation_bundle / "dogleg_start_shared.onnx", threads=1)
    cameras, observations = np.zeros((1, 3, 3, 4), np.float32), np.zeros((4, 3, 2), np.float32)
    assert [a.shape for a in graph(cameras, observations)] == [(3, 4), (4,), (8, 6, 4), (16, 4), (4,)]
    with pytest.raises(InputError, match="takes 2 inputs"):
        graph(cameras)
    rejected = r"dogleg_start_shared.onnx rejected its inputs \(cameras \(1, 3, 3, 4\) float64"
    with pytest.raises(InputError, match=rejected):
        graph(cameras.astype(np.float64), observations)
