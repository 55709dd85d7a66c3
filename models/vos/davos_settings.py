"""The settings of the DAVOS (and LWL) tracker (thesis ch. 6; paper E), shared by the tracker, the system that
trains it and the ONNX export's settings file."""

from __future__ import annotations

from dataclasses import dataclass

from core.errors import InputError
from core.settings import SettingsMixin
from models.vos.memory import check_keep_first


@dataclass(frozen=True)
class DAVOSSettings(SettingsMixin):
    """How the DAVOS tracker segments a video (defaults: the paper's inference settings, DAVOS ``eval/l2dub.py``).

    Attributes:
        init_iters: steepest-descent steps on a new object's first frame (20).
        update_iters: steps after each update (5); update_every: update when frame % update_every == 0 (1).
        memory_size: sample memory capacity (32); learning_rate: its weight decay rate (0.1).
        keep_first: share of the total memory weight the first frame always keeps, never replaced (LWL 0.25;
            0 = the plain decay rule).
        winner_takes_all: regenerate distractors by eqs. 6.1-6.5 (True) or as the soft union of the other
            objects (the ablation, False).
        use_distractors: feed the distractor channel (a DAVOS network); False with a two-channel network
            labels every distractor 0, an LWL network (one channel) has none.
    """

    init_iters: int = 20
    update_iters: int = 5
    update_every: int = 1
    memory_size: int = 32
    learning_rate: float = 0.1
    keep_first: float = 0.25
    winner_takes_all: bool = True
    use_distractors: bool = True

    KIND = "DAVOS tracker"

    def __post_init__(self) -> None:
        for name in ("init_iters", "update_iters"):
            if getattr(self, name) < 0:
                raise InputError(f"tracker setting {name} must be >= 0, got {getattr(self, name)}")
        for name in ("update_every", "memory_size"):
            if getattr(self, name) < 1:
                raise InputError(f"tracker setting {name} must be at least 1, got {getattr(self, name)}")
        if not 0 < self.learning_rate < 1:
            raise InputError(f"tracker setting learning_rate must lie in (0, 1), got {self.learning_rate}")
        check_keep_first(self.keep_first, self.memory_size)
