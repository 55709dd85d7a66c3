"""Whether the code runs inside an export (``torch.export`` / ONNX), where some ops take another form."""

import torch
from torch import Tensor


def exporting() -> bool:
    """True while ``torch.export`` or the ONNX exporter traces the code."""
    return torch.compiler.is_exporting() or torch.onnx.is_in_onnx_export()


def spread(x: Tensor, size: int, axis: int = -1) -> Tensor:
    """``x``, of length 1 along ``axis`` (-1 or -2), as the factor of a product with values of length ``size``
    there: unchanged in eager mode (the product broadcasts it); in an export repeated along that axis as a matrix
    product with ones (exact: each value times 1). onnxruntime broadcasts over outer axes in long contiguous runs
    but over a short inner axis one run at a time, several times slower, and its ``Expand`` is such a broadcast
    too."""
    if not exporting():
        return x
    if axis == -1:
        return torch.matmul(x, torch.ones(1, size, device=x.device, dtype=x.dtype))
    if axis == -2:
        return torch.matmul(torch.ones(size, 1, device=x.device, dtype=x.dtype), x)
    raise ValueError(f"spread takes axis -1 or -2, got {axis}")


def outer_product(per_point: Tensor, table: Tensor) -> Tensor:
    """``(R, P, K)`` products of ``per_point`` ``(P, 1)`` and ``table`` ``(R, 1, K)``; in an export a matrix product
    of inner size 1 (the same products), which onnxruntime runs about 7x faster than the doubly broadcast ``Mul``."""
    return torch.matmul(per_point, table) if exporting() else per_point * table
