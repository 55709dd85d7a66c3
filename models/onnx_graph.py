"""Exported ONNX graphs run by onnxruntime on the CPU, called with torch tensors like the modules they replace."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch

from core.errors import InputError


def onnx_session(path: str | Path, threads: int | None = None) -> ort.InferenceSession:
    """CPU onnxruntime session with sequential execution and ``threads`` intra-op threads (default: ORT's).

    A missing or unreadable graph is an ``InputError`` naming the file.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"ONNX graph not found: {path}")
    options = ort.SessionOptions()
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.inter_op_num_threads = 1
    if threads:
        options.intra_op_num_threads = threads
    try:
        return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    except Exception as err:  # onnxruntime raises its own exception types for corrupt files
        raise InputError(f"{path} is not a readable ONNX graph: {err}") from err


def run_onnx(session: ort.InferenceSession, *inputs: torch.Tensor) -> list[np.ndarray]:
    """Run ``session`` on tensors given in the graph's input order; returns the outputs as numpy arrays."""
    names = [i.name for i in session.get_inputs()]
    if len(names) != len(inputs):
        raise InputError(f"the ONNX graph takes {len(names)} inputs ({', '.join(names)}), got {len(inputs)}")
    try:
        return session.run(None, {n: t.detach().cpu().numpy() for n, t in zip(names, inputs, strict=True)})
    except Exception as err:
        if not type(err).__module__.startswith("onnxruntime"):
            raise
        shapes = ", ".join(f"{n} {tuple(t.shape)}" for n, t in zip(names, inputs, strict=True))
        raise InputError(f"the ONNX graph rejected its inputs ({shapes}): {err}") from err


class OnnxGraph:
    """A graph as a callable: tensors in (graph input order), a tensor out (a tuple when it has several outputs).

    Args:
        path: the ``.onnx`` file; threads: onnxruntime intra-op threads (default: onnxruntime's).
    """

    def __init__(self, path: str | Path, threads: int | None = None) -> None:
        self.path = Path(path)
        self.session = onnx_session(self.path, threads)
        self.input_names = [i.name for i in self.session.get_inputs()]
        self.output_names = [o.name for o in self.session.get_outputs()]

    def __call__(self, *inputs: torch.Tensor) -> torch.Tensor | tuple[torch.Tensor, ...]:
        out = tuple(torch.from_numpy(a) for a in run_onnx(self.session, *inputs))
        return out[0] if len(out) == 1 else out

    def __repr__(self) -> str:
        return f"OnnxGraph({str(self.path)!r}, inputs={self.input_names}, outputs={self.output_names})"
