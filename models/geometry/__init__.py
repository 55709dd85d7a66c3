"""Multi-view geometry: batched N-view triangulation (thesis chapter 2)."""

from models.geometry.dlt import TriangulateDLT, triangulate_dlt
from models.geometry.dogleg import DoglegTriangulation, TriangulateDogleg, triangulate_dogleg
from models.geometry.midpoint import TriangulateMidpoint, triangulate_midpoint
from models.geometry.polynomial import (
    TriangulatePolynomial,
    correct_matches,
    fundamental_from_cameras,
    triangulate_polynomial,
)
from models.geometry.projection import Triangulation, project, reprojection_cost, reprojection_residuals

__all__ = [
    "DoglegTriangulation",
    "TriangulateDLT",
    "TriangulateDogleg",
    "TriangulateMidpoint",
    "TriangulatePolynomial",
    "Triangulation",
    "correct_matches",
    "fundamental_from_cameras",
    "project",
    "reprojection_cost",
    "reprojection_residuals",
    "triangulate_dlt",
    "triangulate_dogleg",
    "triangulate_midpoint",
    "triangulate_polynomial",
]
