"""``models.export_mode``: ``spread`` unchanged in eager mode, repeated exactly along the axis while exporting, and
exported as a matrix product that onnxruntime runs to the same values; ``outer_product`` the same products in both
modes."""

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch

from export.onnx import export_onnx
from models.export_mode import outer_product, spread


def test_spread_is_the_identity_in_eager_mode() -> None:
    x = torch.randn(5, 1, generator=torch.Generator().manual_seed(0))
    assert spread(x, 7) is x


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_spread_while_exporting_repeats_exactly(monkeypatch, dtype) -> None:
    gen = torch.Generator().manual_seed(1)
    per_point = torch.randn(6, 1, generator=gen, dtype=dtype) * 1e3
    table = torch.randn(4, 1, 3, generator=gen, dtype=dtype)
    monkeypatch.setattr(torch.compiler, "is_exporting", lambda: True)
    last, middle = spread(per_point, 3), spread(table, 6, -2)
    assert last.shape == (6, 3) and middle.shape == (4, 6, 3)
    assert torch.equal(last, per_point.expand(6, 3)) and torch.equal(middle, table.expand(4, 6, 3))  # bit-exact
    with pytest.raises(ValueError, match="axis -1 or -2"):
        spread(table, 6, 0)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_outer_product_is_the_broadcast_product_in_both_modes(monkeypatch, dtype) -> None:
    gen = torch.Generator().manual_seed(3)
    per_point, table = torch.randn(9, 1, generator=gen, dtype=dtype), torch.randn(5, 1, 4, generator=gen, dtype=dtype)
    expected = per_point[None] * table  # (5, 9, 4) by broadcasting
    assert torch.equal(outer_product(per_point, table), expected)
    monkeypatch.setattr(torch.compiler, "is_exporting", lambda: True)
    assert torch.equal(outer_product(per_point, table), expected)  # the matrix product of inner size 1: exact


class _Product(torch.nn.Module):
    def forward(self, spectra: torch.Tensor, per_point: torch.Tensor) -> torch.Tensor:
        return spectra * spread(per_point, spectra.shape[-1])


@pytest.mark.slow  # ONNX export
def test_exported_spread_matches_the_broadcast_product(tmp_path) -> None:
    gen = torch.Generator().manual_seed(2)
    spectra, per_point = torch.randn(5, 40, 6, generator=gen), torch.randn(40, 1, generator=gen)
    path = export_onnx(_Product(), (spectra, per_point), tmp_path / "product.onnx", ["spectra", "per_point"], ["out"])
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    got = session.run(None, {"spectra": spectra.numpy(), "per_point": per_point.numpy()})[0]
    np.testing.assert_array_equal(got, (spectra * per_point).numpy())
    assert "MatMul" in {node.op_type for node in onnx.load(path).graph.node}
