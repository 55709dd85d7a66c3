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

__all__ = [
    "METHODS",
    "BlockGridRatio",
    "GoodFeaturesToTrack",
    "PointTracker",
    "TrackerState",
    "block_grid_ratio",
    "extract_patches",
    "good_features_to_track",
    "image_pyramid",
]
