"""The FRTM tracker on exported graphs (``export.vos_onnx``): the same host loop as ``FRTMTracker``
(``FRTMLoop``), with the backbone, target models, decoder, memory insertion and filter updates in onnxruntime.

Host-side work stays in PyTorch/OpenCV: first-frame augmentation, memory initialisation, merging.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from core.errors import InputError
from models.onnx_graph import OnnxGraph
from models.vos.memory import Memory
from models.vos.target_model import target_model_init
from models.vos.tracker import FRTMLoop
from models.vos.tracker_settings import FRTMSettings

#: The graphs of an FRTM export, ``frtm_<name>.onnx``.
GRAPHS = ("frame", "features", "init", "insert", "update")
#: The export's settings file: ``{"settings": FRTMSettings.to_dict(), "in_channels": D}``.
SETTINGS_FILE = "frtm_onnx.json"


def read_export_settings(onnx_dir: str | Path) -> tuple[FRTMSettings, int]:
    """(tracker settings, target-model input channels D) of an FRTM export folder; ``InputError`` when a graph
    or the settings file is missing or the settings are unreadable."""
    d = Path(onnx_dir)
    missing = [f"frtm_{g}.onnx" for g in GRAPHS if not (d / f"frtm_{g}.onnx").is_file()]
    if not (d / SETTINGS_FILE).is_file():
        missing.append(SETTINGS_FILE)
    if missing:
        raise InputError(f"{d} is not an FRTM ONNX export (missing {', '.join(missing)})")
    try:
        stored = json.loads((d / SETTINGS_FILE).read_text())
        return FRTMSettings.from_dict(stored["settings"]), int(stored["in_channels"])
    except (ValueError, KeyError, TypeError) as err:
        raise InputError(f"{d / SETTINGS_FILE} is not an FRTM export settings file ({err})") from err


class OnnxFRTMTracker(FRTMLoop):
    """FRTM video object segmentation on the graphs of ``export.vos_onnx.export_frtm`` (CPU onnxruntime).

    The per-object graphs (init, insert, update) take one object at a time (grouped convolutions need a static
    group count), so this tracker loops over objects.

    Args:
        onnx_dir: the export folder; threads: onnxruntime intra-op threads per graph (default: onnxruntime's).
    """

    def __init__(self, onnx_dir: str | Path, threads: int | None = None) -> None:
        settings, self.in_channels = read_export_settings(onnx_dir)
        self.graphs = {g: OnnxGraph(Path(onnx_dir) / f"frtm_{g}.onnx", threads) for g in GRAPHS}
        super().__init__(settings)

    def target_features(self, images: torch.Tensor) -> torch.Tensor:
        return self.graphs["features"](images.float())

    def fit_target_models(self, x, y, v, gamma):
        s = self.settings
        wp0, wf0 = target_model_init(1, x.shape[2], s.channels, s.kernel_size, s.seed)
        fits = [self.graphs["init"](x[i : i + 1], y[i : i + 1], v[i : i + 1], gamma[i : i + 1], wp0, wf0)
                for i in range(x.shape[0])]
        return torch.cat([wp for wp, _ in fits]), torch.cat([wf for _, wf in fits])

    def segment_frame(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        start = self._tic(image.device)
        logits, z = self.graphs["frame"](image[None].float(), self.wp, self.wf)
        self._toc("frame", start, image.device)
        return logits, z

    def insert_samples(self, z: torch.Tensor, y: torch.Tensor) -> None:
        mem = self.memory
        rows = [self.graphs["insert"](*(t[i : i + 1] for t in mem), z[i : i + 1], y[i : i + 1])
                for i in range(z.shape[0])]
        self.memory = Memory(*(torch.cat(col) for col in zip(*rows, strict=True)))

    def optimize_filters(self) -> None:
        mem = self.memory
        n = max(2, int((mem.weights > 0).sum(1).max()))
        if self.cg_state is None:
            self.cg_state = (torch.zeros_like(self.wf), torch.ones(self.wf.shape[0]), torch.zeros_like(self.wf))
        p, rho, r_prev = self.cg_state
        rows = []
        for i in range(self.wf.shape[0]):
            slots = [t[i : i + 1, :n] for t in mem[:4]]
            rows.append(self.graphs["update"](*slots, self.wf[i : i + 1], p[i : i + 1], rho[i : i + 1],
                                              r_prev[i : i + 1]))
        wf, p, rho, r_prev = (torch.cat(col) for col in zip(*rows, strict=True))
        self.wf, self.cg_state = wf, (p, rho, r_prev)
