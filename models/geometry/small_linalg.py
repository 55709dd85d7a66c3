"""Closed-form 3x3 linear algebra on matrices given entry by entry.

Matrices are nested tuples of same-shaped tensors (one tensor per entry, each holding that entry for a whole
batch), so every formula below is a handful of element-wise ops: no ``torch.linalg`` (which neither exports to
ONNX nor suits millions of 3x3 systems), any device and dtype, and fusable by ``torch.compile``.
A symmetric matrix is given by its six unique entries ``(h00, h11, h22, h01, h02, h12)``.
"""

from __future__ import annotations

from collections.abc import Sequence

from torch import Tensor

Matrix3 = tuple[tuple[Tensor, Tensor, Tensor], tuple[Tensor, Tensor, Tensor], tuple[Tensor, Tensor, Tensor]]


def adjugate3(A: Matrix3) -> tuple[Matrix3, Tensor]:
    """Adjugate and determinant of a 3x3 matrix, so that ``A adj(A) = det(A) I``."""
    (a, b, c), (d, e, f), (g, h, i) = A
    adj = (
        (e * i - f * h, c * h - b * i, b * f - c * e),
        (f * g - d * i, a * i - c * g, c * d - a * f),
        (d * h - e * g, b * g - a * h, a * e - b * d),
    )
    det = a * adj[0][0] + b * adj[1][0] + c * adj[2][0]
    return adj, det


def matvec3(A: Sequence[Sequence[Tensor]], v: Sequence[Tensor]) -> tuple[Tensor, Tensor, Tensor]:
    """``A v`` for a 3x3 matrix and a 3-vector given as components."""
    return tuple(row[0] * v[0] + row[1] * v[1] + row[2] * v[2] for row in A)  # type: ignore[return-value]


def solve_sym3(H: Sequence[Tensor], b: Sequence[Tensor]) -> tuple[tuple[Tensor, Tensor, Tensor], Tensor]:
    """Solve ``H x = b`` for symmetric 3x3 ``H`` (six entries) and ``b`` (three components).

    Returns:
        x: three components of the solution (non-finite where ``H`` is singular) and ``det(H)``.
    """
    h00, h11, h22, h01, h02, h12 = H
    c00 = h11 * h22 - h12 * h12
    c01 = h02 * h12 - h01 * h22
    c02 = h01 * h12 - h02 * h11
    c11 = h00 * h22 - h02 * h02
    c12 = h01 * h02 - h00 * h12
    c22 = h00 * h11 - h01 * h01
    det = h00 * c00 + h01 * c01 + h02 * c02
    x = matvec3(((c00, c01, c02), (c01, c11, c12), (c02, c12, c22)), b)
    return (x[0] / det, x[1] / det, x[2] / det), det


def sym3_quadratic_form(H: Sequence[Tensor], v: Sequence[Tensor]) -> Tensor:
    """``v^T H v`` for symmetric ``H`` (six entries) and a 3-vector ``v``."""
    h00, h11, h22, h01, h02, h12 = H
    v0, v1, v2 = v
    return h00 * v0 * v0 + h11 * v1 * v1 + h22 * v2 * v2 + 2 * (h01 * v0 * v1 + h02 * v0 * v2 + h12 * v1 * v2)


def sym3_smallest_eigenvalue_estimate(H: Sequence[Tensor], det: Tensor) -> Tensor:
    """``det(H) / e2(H)`` with ``e2`` the sum of principal 2x2 minors of a PSD matrix.

    Approaches the smallest eigenvalue when that one is much smaller than the others, the case it detects.
    """
    h00, h11, h22, h01, h02, h12 = H
    e2 = h00 * h11 - h01 * h01 + h00 * h22 - h02 * h02 + h11 * h22 - h12 * h12
    return det / e2

#: Row/column of each of the six unique entries of a symmetric 3x3 matrix, in the order used above.
SYM3_INDEX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
