"""onnxruntime sessions of the deployment runtime: the one place that opens a graph, chooses its execution
provider and runs it on numpy arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnxruntime as ort

from core.errors import InputError

#: Execution providers by the name the commands take (``--provider``); each falls back to the CPU for the nodes it
#: cannot run. TensorRT also lists CUDA, which runs what TensorRT does not take.
PROVIDERS = {
    "cpu": ("CPUExecutionProvider",),
    "cuda": ("CUDAExecutionProvider", "CPUExecutionProvider"),
    "tensorrt": ("TensorrtExecutionProvider", "CUDAExecutionProvider", "CPUExecutionProvider"),
    "coreml": ("CoreMLExecutionProvider", "CPUExecutionProvider"),
}


def session_providers(provider: str = "cpu") -> list[str]:
    """onnxruntime's provider list for ``provider`` (a key of ``PROVIDERS``); ``InputError`` when this
    onnxruntime build lacks it."""
    if provider not in PROVIDERS:
        raise InputError(f"execution provider must be one of {', '.join(PROVIDERS)}, got {provider!r}")
    wanted = PROVIDERS[provider]
    available = ort.get_available_providers()
    if wanted[0] not in available:
        raise InputError(f"execution provider {provider!r} ({wanted[0]}) is not in this onnxruntime build "
                         f"(available: {', '.join(available)}); install the matching onnxruntime package")
    return [p for p in wanted if p in available]


def onnx_session(path: str | Path, threads: int | None = None, provider: str = "cpu") -> ort.InferenceSession:
    """Session of the graph ``path``: sequential execution, ``threads`` intra-op threads (default: onnxruntime's),
    on ``provider``. A missing or unreadable graph is an ``InputError`` naming the file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"ONNX graph not found: {path}")
    options = ort.SessionOptions()
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.inter_op_num_threads = 1
    if threads:
        options.intra_op_num_threads = threads
    options.log_severity_level = 3  # warnings about unused initialisers etc. say nothing to a user
    try:
        return ort.InferenceSession(str(path), options, providers=session_providers(provider))
    except InputError:
        raise
    except Exception as err:  # onnxruntime raises its own exception types for corrupt files
        raise InputError(f"{path} is not a readable ONNX graph: {' '.join(str(err).split())}") from err


class Graph:
    """An exported graph as a callable on numpy arrays: inputs in the graph's input order, one array out (a tuple
    when the graph has several outputs). Inputs it rejects (wrong shape or type) are an ``InputError`` naming
    the graph and the shapes given.

    Args:
        path: the ``.onnx`` file; threads: intra-op threads (default: onnxruntime's); provider: a key of
            ``PROVIDERS``.
    """

    def __init__(self, path: str | Path, threads: int | None = None, provider: str = "cpu") -> None:
        self.path = Path(path)
        self.session = onnx_session(self.path, threads, provider)
        self.input_names = [i.name for i in self.session.get_inputs()]
        self.output_names = [o.name for o in self.session.get_outputs()]

    def __call__(self, *inputs: np.ndarray) -> np.ndarray | tuple[np.ndarray, ...]:
        if len(inputs) != len(self.input_names):
            raise InputError(f"{self.path.name} takes {len(self.input_names)} inputs ({', '.join(self.input_names)})"
                             f", got {len(inputs)}")
        feed = {name: np.asarray(a) for name, a in zip(self.input_names, inputs, strict=True)}
        try:
            out = self.session.run(None, feed)
        except Exception as err:
            if not type(err).__module__.startswith("onnxruntime"):
                raise
            shapes = ", ".join(f"{n} {a.shape} {a.dtype}" for n, a in feed.items())
            raise InputError(f"{self.path.name} rejected its inputs ({shapes}): {' '.join(str(err).split())}") from err
        return out[0] if len(out) == 1 else tuple(out)

    def __repr__(self) -> str:
        return f"Graph({str(self.path)!r}, inputs={self.input_names}, outputs={self.output_names})"
