"""Static int8 quantization of the exported CNN graphs (onnxruntime's quantization tools): ``quant_pre_process``,
then QDQ with unsigned 8-bit activations and signed 8-bit per-channel weights, MinMax calibrated on inputs recorded
while the float32 runtime runs on the project's own synthetic data. Only the ``Conv`` nodes are quantized, so
the correlation-filter parts inside a graph (the target model's projection and filter, the matcher) stay float32,
and the DCF optimiser graphs are never quantized (their fixed-point iterations amplify the rounding).
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from onnxruntime.quantization import CalibrationDataReader, CalibrationMethod, QuantFormat, QuantType, quantize_static
from onnxruntime.quantization.shape_inference import quant_pre_process

from core.errors import InputError
from runtime.session import Graph


class RecordingGraph:
    """Wraps a ``runtime.session.Graph``: calls pass through, and the inputs of the first ``limit`` calls are kept
    (by input name) as calibration samples."""

    def __init__(self, graph: Graph, limit: int = 64) -> None:
        self.graph, self.limit = graph, limit
        self.samples: list[dict[str, np.ndarray]] = []

    def __call__(self, *inputs: np.ndarray):
        if len(self.samples) < self.limit:
            self.samples.append({n: np.array(a) for n, a in zip(self.graph.input_names, inputs, strict=True)})
        return self.graph(*inputs)


class _Samples(CalibrationDataReader):
    def __init__(self, samples: Sequence[dict[str, np.ndarray]]) -> None:
        self.samples = iter(samples)

    def get_next(self) -> dict[str, np.ndarray] | None:
        return next(self.samples, None)


def quantize_graph(fp32: str | Path, out: str | Path, samples: Sequence[dict[str, np.ndarray]]) -> Path:
    """Write the int8 QDQ version of the graph ``fp32`` to ``out``, calibrated on ``samples`` (graph inputs by name)."""
    if not samples:
        raise InputError(f"no calibration samples were recorded for {Path(fp32).name}")
    with tempfile.TemporaryDirectory() as tmp:
        prepared = Path(tmp) / "prepared.onnx"
        quant_pre_process(str(fp32), str(prepared), skip_symbolic_shape=True)
        quantize_static(str(prepared), str(out), _Samples(samples), quant_format=QuantFormat.QDQ,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8, per_channel=True,
                        calibrate_method=CalibrationMethod.MinMax, op_types_to_quantize=["Conv"])
    return Path(out)


def graph_ms(path: str | Path, sample: dict[str, np.ndarray], repeats: int = 5) -> float:
    """Best-of-``repeats`` milliseconds of one call of the graph ``path`` on ``sample`` with one thread."""
    graph = Graph(path, threads=1)
    inputs = [sample[n] for n in graph.input_names]
    graph(*inputs)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        graph(*inputs)
        best = min(best, time.perf_counter() - start)
    return best * 1e3


def quantize_bundle_graphs(folder: Path, recorded: dict[str, RecordingGraph]) -> dict[str, dict]:
    """Replace the graphs ``<name>.onnx`` of ``folder`` named in ``recorded`` by their int8 versions; returns per
    graph the size in bytes and the milliseconds per call (one thread) of both versions."""
    report = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, recorder in recorded.items():
            fp32 = Path(tmp) / f"{name}_fp32.onnx"
            shutil.copyfile(folder / f"{name}.onnx", fp32)
            quantize_graph(fp32, folder / f"{name}.onnx", recorder.samples)
            sample = recorder.samples[0]
            report[name] = {"fp32_bytes": fp32.stat().st_size, "int8_bytes": (folder / f"{name}.onnx").stat().st_size,
                            "fp32_ms": graph_ms(fp32, sample), "int8_ms": graph_ms(folder / f"{name}.onnx", sample),
                            "calibration_samples": len(recorder.samples)}
    return report
