"""ONNX export of the pretrained EfficientNet-Lite backbone: onnxruntime matches PyTorch to 1e-4."""

import pytest
import torch
from torch import nn
from torch.export import Dim

from export.onnx import export_onnx
from models.backbones import EfficientNetLiteBackbone
from runtime.session import Graph

pytestmark = pytest.mark.slow  # ONNX export


class Stages(nn.Module):
    """The backbone's stage dict as a tuple of graph outputs."""

    def __init__(self, backbone: nn.Module) -> None:
        super().__init__()
        self.backbone = backbone

    def forward(self, image: torch.Tensor) -> tuple[torch.Tensor, ...]:
        return tuple(self.backbone(image).values())


def test_backbone_onnx_matches_pytorch(tmp_path) -> None:
    model = Stages(EfficientNetLiteBackbone("efficientnet_lite0", "imagenet")).eval()
    g = torch.Generator().manual_seed(0)
    h, w = Dim("H", min=32, max=1024), Dim("W", min=32, max=1024)
    path = export_onnx(model, (torch.rand(1, 3, 64, 96, generator=g),), tmp_path / "backbone.onnx", ["image"],
                       ["layer1", "layer2", "layer3", "layer4"], dynamic_shapes=({2: h, 3: w},))
    graph = Graph(path)
    for size in ((64, 96), (96, 128)):  # H and W are dynamic
        image = torch.rand(1, 3, *size, generator=g)
        with torch.no_grad():
            ref = model(image)
        for got, want in zip(graph(image.numpy()), ref, strict=True):
            assert got.shape == tuple(want.shape)
            assert abs(torch.from_numpy(got) - want).max() <= 1e-4 * max(1.0, float(want.abs().max()))
