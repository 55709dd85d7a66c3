"""Optical-flow data for point tracking: Middlebury ``.flo`` files, Sintel folders, ground-truth tracks from
flow (thesis 3.4) and seeded synthetic sequences with chained ground truth, plain or under stress conditions.
"""

from data.flow.flo import read_flo, write_flo
from data.flow.ground_truth import divergent_flow_mask, sample_bilinear, tracks_from_flow
from data.flow.sintel import SintelPair, read_sintel_pair, read_sintel_sequence
from data.flow.stress import STRESS_CONDITIONS, stress_sequence
from data.flow.synthetic import SyntheticSequence, synthetic_sequence

__all__ = [
    "STRESS_CONDITIONS",
    "SintelPair",
    "SyntheticSequence",
    "divergent_flow_mask",
    "read_flo",
    "read_sintel_pair",
    "read_sintel_sequence",
    "sample_bilinear",
    "stress_sequence",
    "synthetic_sequence",
    "tracks_from_flow",
    "write_flo",
]
