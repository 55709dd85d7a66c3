"""OnnxFRTMTracker without an export: a folder that holds none is named (its runs: tests/export/test_vos_onnx.py)."""

import pytest

from core.errors import InputError
from models.vos.onnx_tracker import OnnxFRTMTracker


def test_missing_export(tmp_path) -> None:
    with pytest.raises(InputError, match="not an FRTM ONNX export"):
        OnnxFRTMTracker(tmp_path)
