"""The settings of the FRTM tracker (thesis ch. 5.3; paper D), shared by the PyTorch tracker, the
onnxruntime tracker and the ONNX export's settings file."""

from __future__ import annotations

from dataclasses import dataclass

from core.errors import InputError
from core.processing_size import check_process_height
from core.search_region import check_search_radius
from core.settings import SettingsMixin
from models.vos.memory import check_keep_first
from models.vos.target_features import check_feature_norm

OPTIMIZERS = ("gauss_newton", "steepest_descent")
OPTIMIZER_DTYPES = ("float32", "float64")


@dataclass(frozen=True)
class FRTMSettings(SettingsMixin):
    """How the FRTM tracker segments a video (defaults: the paper's inference settings).

    Attributes:
        feature_layer: backbone stage the target model reads (stride 16; FRTM: ResNet layer3), or stages joined
            by ``+`` at the first one's resolution (``layer2+layer3``, DAVOS); ``TargetFeatures``.
        feature_norm, feature_scale: ``none``, ``fixed`` (divided by ``feature_scale``) or ``instance_l2``
            (unit-RMS features per frame); ``models.vos.target_features.normalize_features``.
        channels: C, the projection width (96 at inference, 32 in training).
        kernel_size: W_f size (3).
        num_aug: first-frame samples including the original (5).
        memory_size: memory capacity in frames (80); learning_rate: memory weight decay rate (0.1).
        keep_first: share of the total memory weight the first frame (the given mask) always keeps, its slot
            never replaced (LWL's rule, 0.25 there; ``models.vos.memory.memory_insert``); 0 (the paper's FRTM): it
            decays like every other sample.
        update_every: re-optimise W_f when frame % update_every == 0 (8).
        init_schedule / update_schedule: CG iterations per Gauss-Newton step ((5, 10, 10, 10, 10) / (10,)).
        reg: (lambda_p, lambda_f) regularisation of eq. 5.2 (1e-4, 1e-2).
        optimizer: ``gauss_newton`` or ``steepest_descent`` (sum of the schedule as steps).
        pixel_weighting: use the hinge pixel weights with foreground share ``fg_target`` (0.1).
        min_update_pixels: an object's frame enters its memory only with this many pixels above 0.5 (10).
        label_stride: memory labels are stored at 1/label_stride of the image size (1 = full resolution).
        optimizer_dtype: precision of the W_p/W_f fits and updates (``float64``; filters and the CG state are
            kept in the features' precision between calls). In float32 the closed loop (fit -> masks -> memory
            -> update) amplifies rounding: a 1e-6 relative change of the input frames changed up to 7 % of an
            object's mask on a held-out synthetic video; in float64 the masks stayed identical.
        flip_test: with the decoder, average its logits with those of the left-right mirrored frame (test-time
            augmentation, ``models.vos.decoder.flip_averaged_logits``; twice the backbone and decoder work).
        search_radius: an object's mask keeps only its connected components within ``search_radius`` x sqrt(area)
            px of its previous mask of that area (all when none is that near; ``core.search_region``); 0: off.
        score_support: an object's mask keeps only the connected components on which its target model's score
            (upsampled bilinearly) exceeds 0.5 somewhere (``core.search_region.unsupported_components``), after
            the search region: the decoder refines the target model's detections but adds none of its own.
        memory_main_component: the memory learns from each object's largest connected component (soft mask above
            0.5) only, the rest of its soft mask set to 0 there (``core.search_region.main_component``).
        ignore_band: the memory gives zero pixel weight to the pixels outside each object's mask within
            ``ignore_band`` x sqrt(area) px of it (``core.search_region.ignore_band``): the part of an object that
            its mask misses (it grew or turned faster than the target model learnt) does not train the target
            model as background; 0: off.
        use_decoder: False segments by thresholding the upsampled target-model score (``target_model_only``).
        seed: seeds the augmentation and the filter initialisation.
        process_height: rows of the frames the tracker works at, aspect kept (``VideoLoop``: frames resized
            bilinearly, label maps returned at the input size); 0 works at the input size.
    """

    feature_layer: str = "layer3"
    feature_norm: str = "none"
    feature_scale: float = 1.0
    channels: int = 96
    kernel_size: int = 3
    num_aug: int = 5
    memory_size: int = 80
    learning_rate: float = 0.1
    keep_first: float = 0.0
    update_every: int = 8
    init_schedule: tuple[int, ...] = (5, 10, 10, 10, 10)
    update_schedule: tuple[int, ...] = (10,)
    reg: tuple[float, float] = (1e-4, 1e-2)
    optimizer: str = "gauss_newton"
    pixel_weighting: bool = True
    fg_target: float = 0.1
    min_update_pixels: int = 10
    label_stride: int = 1
    optimizer_dtype: str = "float64"
    flip_test: bool = False
    search_radius: float = 0.0
    memory_main_component: bool = False
    ignore_band: float = 0.0
    score_support: bool = False
    use_decoder: bool = True
    seed: int = 0
    process_height: int = 0

    def __post_init__(self) -> None:
        for name in ("init_schedule", "update_schedule", "reg"):  # YAML and JSON give lists
            object.__setattr__(self, name, tuple(getattr(self, name)))
        check_feature_norm(self.feature_norm, self.feature_scale)
        check_search_radius(self.search_radius)
        check_search_radius(self.ignore_band, "ignore_band")
        # a string "false" would read as on
        for name in ("pixel_weighting", "flip_test", "memory_main_component", "score_support", "use_decoder"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"tracker setting {name} must be true or false, got {getattr(self, name)!r}")
        check_process_height(self.process_height)
        if self.optimizer not in OPTIMIZERS:
            raise InputError(f"optimizer must be one of {', '.join(OPTIMIZERS)}, got {self.optimizer!r}")
        if self.optimizer_dtype not in OPTIMIZER_DTYPES:
            raise InputError(f"optimizer_dtype must be 'float32' or 'float64', got {self.optimizer_dtype!r}")
        for name in ("channels", "num_aug", "memory_size", "update_every", "label_stride"):
            if getattr(self, name) < 1:
                raise InputError(f"tracker setting {name} must be at least 1, got {getattr(self, name)}")
        check_keep_first(self.keep_first, self.memory_size)
        if self.kernel_size < 1 or self.kernel_size % 2 == 0:
            raise InputError(f"tracker setting kernel_size must be odd and positive, got {self.kernel_size}")
        if len(self.reg) != 2 or min(self.reg) < 0:
            raise InputError(f"tracker setting reg must be two non-negative numbers, got {self.reg}")
        if not self.init_schedule or not self.update_schedule or min(self.init_schedule + self.update_schedule) < 1:
            raise InputError("tracker settings init_schedule and update_schedule must be non-empty lists of "
                             f"positive iteration counts, got {self.init_schedule} and {self.update_schedule}")
