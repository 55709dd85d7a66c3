"""The dogleg solver as start and step modules: looped by hand it gives eager ``triangulate_dogleg``'s result and
the fp64 optimum; packing round-trips; converged points stay frozen."""

import pytest
import torch

from data.sfm.synthetic import synthetic_cube_scene
from models.geometry import triangulate_dogleg
from models.geometry.dogleg_stages import STATE_ROWS, DoglegStart, DoglegStep, pack_state, unpack_state


def _run_stages(P, x, iterations):
    X0, usable, rows, state, active = DoglegStart()(P, x)
    steps = 0
    while steps < iterations and active.any():
        state, active = DoglegStep()(rows, state, active)
        steps += 1
    cost = 2 * state[3]
    valid = usable & (state[4] > 0) & torch.isfinite(cost)
    return (X0 + state[0:3]).T, cost, valid, ~active & valid, steps


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("shared", [True, False])
def test_stages_match_eager_and_the_fp64_optimum(dtype, shared) -> None:
    s = synthetic_cube_scene(500, num_views=4, noise_px=1.0, seed=3, dtype=dtype)
    P = s.cameras if shared else s.cameras.expand(500, -1, -1, -1).contiguous()
    points, cost, valid, converged, steps = _run_stages(P, s.observations, iterations=5)
    eager = triangulate_dogleg(P, s.observations, iterations=5)
    torch.testing.assert_close(points, eager.points)
    torch.testing.assert_close(cost, eager.cost)
    assert torch.equal(valid, eager.valid) and torch.equal(converged, eager.converged)
    assert 1 <= steps < 5 and converged.all()  # stopped early: every point converged
    optimum = triangulate_dogleg(P.double(), s.observations.double(), iterations=100, tolerance=1e-14).points
    tol = 1e-4 if dtype == torch.float32 else 1e-9
    assert (points.double() - optimum).norm(dim=-1).max() < tol


def test_state_packing_round_trips_and_converged_points_are_frozen() -> None:
    s = synthetic_cube_scene(64, num_views=3, noise_px=1.0, seed=4, dtype=torch.float64)
    _, _, rows, state, active = DoglegStart()(s.cameras, s.observations)
    assert state.shape == (STATE_ROWS, 64) and rows.shape == (8, 6, 64)
    repacked, again = pack_state(unpack_state(state, active))
    assert torch.equal(repacked, state) and torch.equal(again, active)
    frozen = torch.zeros_like(active)
    next_state, next_active = DoglegStep()(rows, state, frozen)
    assert torch.equal(next_state, state) and not next_active.any()
