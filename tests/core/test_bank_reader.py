"""The bank's grid: sub-grid refinement of a best location against a closed form (reading banks is tested with the
writer, tests/data/horizon/test_bank_io.py)."""

import numpy as np

from core.bank_reader import subgrid_refine


def test_subgrid_refine_recovers_quadratic_peak():
    rows, cols = 9, 11
    rr, cc = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    cells = np.stack([rr.ravel(), cc.ravel()], -1)
    peaks = np.array([[4.3, 5.0], [2.0, 7.45], [6.6, 3.8]])
    scores = np.stack([10 - 2 * (cells[:, 0] - r) ** 2 - 0.5 * (cells[:, 1] - c) ** 2 for r, c in peaks])
    best = scores.argmax(1)
    np.testing.assert_allclose(subgrid_refine(scores, cells, rows, cols, best), peaks, atol=1e-12)
    # at the grid border there is no neighbour on one side: no refinement along that axis
    edge = np.stack([10 - (cells[:, 0] - 0.2) ** 2 - (cells[:, 1] - 5.3) ** 2])
    out = subgrid_refine(edge, cells, rows, cols, edge.argmax(1))
    np.testing.assert_allclose(out, [[0.0, 5.3]], atol=1e-12)
    # neighbours outside a search window (-inf) count as missing
    edge[0, (cells[:, 1] == 6)] = -np.inf
    np.testing.assert_allclose(subgrid_refine(edge, cells, rows, cols, edge.argmax(1)), [[0.0, 5.0]], atol=1e-12)
