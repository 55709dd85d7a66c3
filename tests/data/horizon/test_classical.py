"""Classical horizon pipeline (Canny + Hough + eq. 4.1) against the renderer's ground truth."""

import math

import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths, s_curve, tangent_to_row
from core.errors import InputError
from core.raycast import VirtualHorizon
from data.horizon.classical import ClassicalHorizon, hough_tilt, projection_cost
from data.world.dem import generate_archipelago
from data.world.render import Appearance, render_panorama


def test_hough_recovers_tilt_of_an_exact_s_curve():
    height, width = 128, 1024
    pitch = torch.tensor([0.05, -0.02, 0.0], dtype=torch.float64)
    roll = torch.tensor([-0.03, 0.08, 0.1], dtype=torch.float64)
    dip = torch.full((3,), 7e-4, dtype=torch.float64)
    psi = column_azimuths(width, torch.float64)[None].expand(3, -1)
    rows = tangent_to_row(s_curve(psi, pitch, roll) - dip[:, None], height, width).round().long()
    edges = torch.zeros(3, height, width, dtype=torch.bool)
    edges[torch.arange(3)[:, None], rows, torch.arange(width)] = True
    rng = np.random.default_rng(0)  # clutter: 3000 random edge pixels per image
    edges[torch.from_numpy(rng.integers(0, 3, 9000)), torch.from_numpy(rng.integers(0, height, 9000)),
          torch.from_numpy(rng.integers(0, width, 9000))] = True
    p, q, inliers = hough_tilt(edges, dip)
    assert (p - pitch).abs().max() < math.radians(0.03) and (q - roll).abs().max() < math.radians(0.03)
    assert (inliers >= width * 0.9).all()


@pytest.fixture(scope="module")
def world():
    dem = generate_archipelago(size_m=4000, cell=10, seed=5, land_fraction=0.15, max_height=25,
                               forest_height=12)
    sea = np.argwhere(dem.z[100:300, 100:300] == 0) + 100
    rng = np.random.default_rng(3)
    picks = sea[rng.choice(len(sea), 3, replace=False)]
    poses = torch.tensor([[10.0 * c + 5, 4000 - 10.0 * r - 5, 2.5, rng.uniform(0, 2 * math.pi),
                           math.radians(rng.normal(0, 3)), math.radians(rng.normal(0, 3))] for r, c in picks])
    return dem, poses


def test_classical_labels_match_ground_truth(world):
    dem, poses = world
    width, height = 1024, 128
    render_caster = VirtualHorizon(dem, bins=2 * width, max_range=3000.0, step=5.0)
    generator = torch.Generator().manual_seed(1)
    image, truth = render_panorama(render_caster, poses, width, height, Appearance.sample(3, False, generator),
                                   generator)
    classical = ClassicalHorizon(VirtualHorizon(dem, bins=width, max_range=3000.0, step=10.0))
    compass = poses[:, 3] + torch.tensor([0.03, -0.05, 0.06])  # compass errors of 2-3.5 degrees
    labels = classical(image, poses[:, :2], poses[:, 2], compass)
    assert labels.ok.all()
    to_deg = math.degrees
    assert to_deg((labels.pitch - truth.pitch.double()).abs().max()) < 0.1
    assert to_deg((labels.roll - truth.roll.double()).abs().max()) < 0.1
    heading_error = torch.remainder(labels.heading - truth.heading.double() + math.pi, 2 * math.pi) - math.pi
    assert to_deg(heading_error.abs().max()) < 0.2
    assert (labels.horizon_rows - truth.level_horizon_rows.double()).abs().median() < 0.5
    assert (labels.water_rows - truth.level_water_rows.double()).abs().median() < 0.5
    # Pure noise: nothing fits, the fit is rejected.
    noise = torch.rand(1, 3, height, width, generator=generator)
    rejected = classical(noise, poses[:1, :2], poses[:1, 2], compass[:1])
    assert not rejected.ok.any() and rejected.quality.max() < 0.45 < labels.quality.min()


def test_projection_cost_is_zero_on_the_edges():
    height, width = 64, 256
    distance = torch.full((1, height, width), 5.0, dtype=torch.float64)
    distance[0, 31] = 0.0
    distance[0, 30] = distance[0, 32] = 1.0
    psi = column_azimuths(width, torch.float64)[None]
    points_t = torch.full_like(psi, 0.5 / (width / (2 * math.pi)))  # row 31
    angles = torch.tensor([[[0.0, 0.0, 0.3], [0.0, 0.05, 0.3]]], dtype=torch.float64)
    cost = projection_cost(distance, psi, points_t, torch.ones_like(psi), angles, tau=3.0)
    assert cost[0, 0] == pytest.approx(0.0, abs=1e-12) and cost[0, 1] > 1.0


def test_classical_bad_input(world):
    dem, poses = world
    classical = ClassicalHorizon(VirtualHorizon(dem, bins=64, max_range=500.0))
    with pytest.raises(InputError, match=r"\(B, 3, H, W\)"):
        classical(torch.zeros(1, 64, 256), poses[:1, :2], poses[:1, 2], poses[:1, 3])
    with pytest.raises(InputError, match="must match"):
        classical(torch.zeros(2, 3, 32, 256), poses[:1, :2], poses[:1, 2], poses[:1, 3])
    with pytest.raises(InputError, match="outside the DEM"):
        classical(torch.zeros(1, 3, 32, 256), torch.tensor([[-50.0, 10.0]]), poses[:1, 2], poses[:1, 3])
