"""Whether the code runs inside an export (``torch.export`` / ONNX), where some ops take another form."""

import torch


def exporting() -> bool:
    """True while ``torch.export`` or the ONNX exporter traces the code."""
    return torch.compiler.is_exporting() or torch.onnx.is_in_onnx_export()
