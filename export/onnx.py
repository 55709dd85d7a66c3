"""ONNX export with the dynamo exporter and model checking (``runtime.session`` runs the graphs)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import onnx
import torch
from torch import nn

from core.files import partial_name, writable_folder

#: Opset used for every export (DFT needs >= 18; 5-D GridSample needs 20).
OPSET = 20


def export_onnx(
    model: nn.Module,
    args: tuple[torch.Tensor, ...],
    path: str | Path,
    input_names: Sequence[str],
    output_names: Sequence[str],
    dynamic_shapes: Any = None,
    optimize: bool = True,
) -> Path:
    """Export ``model(*args)`` to ``path`` (dynamo exporter, opset 20), check it, and return the path.

    ``optimize`` runs onnxscript's graph optimizer (constant folding, pattern rewrites). Its pattern matching grows
    much faster than linearly with the graph: the unrolled Gauss-Newton/CG graphs of FRTM at the paper's schedule
    (tens of thousands of nodes) did not finish in 50 minutes, so they are exported without it (onnxruntime still
    optimises every graph when it loads it).

    The graph is written beside ``path`` under a temporary name and renamed only after ``onnx.checker`` passed,
    so a failed export leaves no file behind.
    """
    path = Path(path)
    writable_folder(path.parent)
    tmp = partial_name(path)
    model = model.eval()
    program = torch.onnx.export(
        model,
        args,
        dynamo=True,
        opset_version=OPSET,
        input_names=list(input_names),
        output_names=list(output_names),
        dynamic_shapes=dynamic_shapes,
        optimize=optimize,
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
