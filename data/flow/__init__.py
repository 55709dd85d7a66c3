"""Optical-flow data for point tracking: Middlebury ``.flo`` files, Sintel folders, ground-truth tracks from
flow (thesis 3.4), seeded synthetic sequences with chained ground truth, plain or under stress conditions,
real photographs seen through chains of homographies under growing blur, compression or darkness, and real
sequences with known homographies read from folders laid out as the Oxford sets or HPatches.
"""

from data.flow.flo import read_flo, write_flo
from data.flow.ground_truth import divergent_flow_mask, sample_bilinear, tracks_from_flow
from data.flow.homography import HOMOGRAPHY_CONDITIONS, HomographySequence, degrade, homography_sequence
from data.flow.homography_folder import read_homography, read_homography_folder
from data.flow.sintel import SintelPair, read_sintel_pair, read_sintel_sequence
from data.flow.stress import PHOTOMETRIC_CONDITIONS, STRESS_CONDITIONS, stress_frames, stress_sequence
from data.flow.synthetic import SyntheticSequence, synthetic_sequence

__all__ = [
    "HOMOGRAPHY_CONDITIONS",
    "HomographySequence",
    "PHOTOMETRIC_CONDITIONS",
    "STRESS_CONDITIONS",
    "SintelPair",
    "SyntheticSequence",
    "degrade",
    "divergent_flow_mask",
    "homography_sequence",
    "read_flo",
    "read_homography",
    "read_homography_folder",
    "read_sintel_pair",
    "read_sintel_sequence",
    "sample_bilinear",
    "stress_frames",
    "stress_sequence",
    "synthetic_sequence",
    "tracks_from_flow",
    "write_flo",
]
