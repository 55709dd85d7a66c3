"""OnnxGraph: an exported graph called like the module it replaces; missing and corrupt files are named."""

import pytest
import torch
from torch import nn

from core.errors import InputError
from export.onnx import export_onnx
from models.onnx_graph import OnnxGraph


class TwoOutputs(nn.Module):
    def forward(self, x: torch.Tensor, y: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return x @ y, (x - 1).relu()


def test_graph_matches_the_module_and_checks_its_inputs(tmp_path) -> None:
    g = torch.Generator().manual_seed(0)
    x, y = torch.randn(3, 4, generator=g), torch.randn(4, 2, generator=g)
    path = export_onnx(TwoOutputs(), (x, y), tmp_path / "two.onnx", ["x", "y"], ["xy", "relu"])
    graph = OnnxGraph(path)
    assert graph.input_names == ["x", "y"] and graph.output_names == ["xy", "relu"]
    got = graph(x, y)
    ref = TwoOutputs()(x, y)
    for a, b in zip(got, ref, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-6)
    with pytest.raises(InputError, match=r"takes 2 inputs \(x, y\), got 1"):
        graph(x)


def test_missing_and_corrupt_graphs(tmp_path) -> None:
    with pytest.raises(InputError, match="ONNX graph not found: .*nothing.onnx"):
        OnnxGraph(tmp_path / "nothing.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a protobuf")
    with pytest.raises(InputError, match="bad.onnx is not a readable ONNX graph"):
        OnnxGraph(bad)
