"""Triangulate the tracks of a reconstruction and compare with its bundle-adjusted points."""

from __future__ import annotations

import time

import torch

from core.errors import InputError
from data.sfm.reconstruction import Reconstruction, scene_radius
from models.geometry.methods import FIXED_VIEWS, METHODS
from models.geometry.projection import Triangulation


def evaluate_reconstruction(
    recon: Reconstruction, views: int = 3, method: str = "dogleg", dtype: torch.dtype = torch.float64
) -> tuple[dict, Triangulation, torch.Tensor]:
    """Triangulate every track with at least ``views`` views from its first ``views`` views.

    Returns:
        report: ``method, views, count, valid, err3d_median_rel, err3d_mean_rel`` (3D distance to the file's
        points over the scene radius), ``reproj_rms`` (RMS reprojection distance over observations, px) and
        ``points_per_s``; the ``Triangulation``; the (B,) indices of the triangulated points in the file.
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    if FIXED_VIEWS.get(method, views) != views:
        raise InputError(f"method {method} takes exactly {FIXED_VIEWS[method]} views, not {views} (use --views 2)")
    P, x, reference, index = recon.tracks(views)
    if len(index) == 0:
        raise InputError(f"no track of the reconstruction has {views} registered views")
    P, x = P.to(dtype), x.to(dtype)
    solve = METHODS[method]
    solve(P[:1], x[:1])  # warm-up
    start = time.perf_counter()
    result = solve(P, x)
    seconds = time.perf_counter() - start
    valid = result.valid
    n_valid = int(valid.sum())
    err = (result.points.double() - reference).norm(dim=-1)[valid] / scene_radius(recon.points)
    report = {
        "method": method,
        "views": views,
        "count": int(len(index)),
        "valid": n_valid,
        "err3d_median_rel": float(err.median()) if n_valid else float("nan"),
        "err3d_mean_rel": float(err.mean()) if n_valid else float("nan"),
        "reproj_rms": float((result.cost[valid].double().sum() / (views * max(n_valid, 1))).sqrt()),
        "points_per_s": len(index) / seconds,
    }
    return report, result, index
