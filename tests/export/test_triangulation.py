"""The triangulation bundle: both dogleg graphs (cameras shared and per point) match PyTorch in onnxruntime, bad
export arguments."""

import pytest

from core.errors import InputError
from export.triangulation import export_bundle, parity

pytestmark = pytest.mark.slow  # ONNX export


def test_bundle_matches_pytorch(triangulation_bundle) -> None:
    assert parity(triangulation_bundle, points=3000) < 1e-4  # cube of half size 1


def test_bad_export_arguments(tmp_path) -> None:
    with pytest.raises(InputError, match="--views must be at least 2"):
        export_bundle(tmp_path / "b", views=1)
    with pytest.raises(InputError, match="--iterations must be at least 1"):
        export_bundle(tmp_path / "b", iterations=0)
