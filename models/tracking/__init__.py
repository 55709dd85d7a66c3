"""Point tracking with discriminative correlation filters (thesis ch. 3.4)."""

from models.tracking.compression import BlockGridRatio, block_grid_ratio
from models.tracking.good_features import GoodFeaturesToTrack, good_features_to_track
from models.tracking.point_tracker import (
    METHODS,
    PointTracker,
    TrackerState,
    extract_patches,
    image_pyramid,
)
from models.tracking.turn import CameraTurn, camera_turn

__all__ = [
    "METHODS",
    "BlockGridRatio",
    "CameraTurn",
    "GoodFeaturesToTrack",
    "PointTracker",
    "TrackerState",
    "block_grid_ratio",
    "camera_turn",
    "extract_patches",
    "good_features_to_track",
    "image_pyramid",
]
