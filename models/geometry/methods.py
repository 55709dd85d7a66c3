"""Triangulation methods by name, as the command line and the benchmarks select them."""

from __future__ import annotations

from collections.abc import Callable

from torch import Tensor

from models.geometry.dlt import triangulate_dlt
from models.geometry.dogleg import triangulate_dogleg
from models.geometry.midpoint import triangulate_midpoint
from models.geometry.polynomial import triangulate_polynomial
from models.geometry.projection import Triangulation

METHODS: dict[str, Callable[[Tensor, Tensor], Triangulation]] = {
    "dogleg": triangulate_dogleg,
    "midpoint": triangulate_midpoint,
    "dlt": triangulate_dlt,
    "polynomial": triangulate_polynomial,
}

#: Number of views a method is limited to (absent: any N >= 2).
FIXED_VIEWS = {"polynomial": 2}
