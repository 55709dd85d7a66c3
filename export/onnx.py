"""ONNX export with the dynamo exporter, model checking, and onnxruntime parity checks."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import onnx
import onnxruntime as ort
import torch
from torch import nn

#: Opset used for every export (DFT needs >= 18; 5-D GridSample needs 20).
OPSET = 20


def export_onnx(
    model: nn.Module,
    args: tuple[torch.Tensor, ...],
    path: str | Path,
    input_names: Sequence[str],
    output_names: Sequence[str],
    dynamic_shapes: Any = None,
) -> Path:
    """Export ``model(*args)`` to ``path`` (dynamo exporter, opset 20), check it, and return the path.

    The graph is written beside ``path`` under a temporary name and renamed only after ``onnx.checker`` passed,
    so a failed export leaves no file behind.
    """
    path = Path(path)
    tmp = path.with_name(path.stem + ".partial.onnx")
    model = model.eval()
    program = torch.onnx.export(
        model,
        args,
        dynamo=True,
        opset_version=OPSET,
        input_names=list(input_names),
        output_names=list(output_names),
        dynamic_shapes=dynamic_shapes,
        external_data=False,
        verbose=False,
    )
    try:
        program.save(str(tmp))
        onnx.checker.check_model(onnx.load(str(tmp)), full_check=True)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def onnx_session(path: str | Path, threads: int | None = None) -> ort.InferenceSession:
    """CPU onnxruntime session with sequential execution and ``threads`` intra-op threads (default: ORT's)."""
    options = ort.SessionOptions()
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.inter_op_num_threads = 1
    if threads:
        options.intra_op_num_threads = threads
    return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])


def run_onnx(session: ort.InferenceSession, *inputs: torch.Tensor) -> list[np.ndarray]:
    """Run ``session`` on tensors given in the graph's input order; returns the outputs as numpy arrays."""
    names = [i.name for i in session.get_inputs()]
    if len(names) != len(inputs):
        raise ValueError(f"the ONNX graph takes {len(names)} inputs ({', '.join(names)}), got {len(inputs)}")
    return session.run(None, {n: t.detach().cpu().numpy() for n, t in zip(names, inputs, strict=True)})
