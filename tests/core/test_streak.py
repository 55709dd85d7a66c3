"""Straight streaks: the kernel's length, direction and variance, the blur of an impulse, the covariance of a
chain of streaks against the kernels' own second moments, the change between two chains against NumPy's
eigenvalues, the decision from the cepstral scores, bad input."""

import math

import numpy as np
import pytest

from core.errors import InputError
from core.streak import (
    MIN_QUARTER,
    quarter_slices,
    streak_blur,
    streak_change,
    streak_covariance,
    streak_found,
    streak_kernel,
    streak_uniform,
    streaks_matched,
)


def test_streak_kernel_is_a_line_of_the_given_length_and_direction():
    kernel = streak_kernel(9.0, np.pi / 2)  # along y
    assert kernel.sum() == pytest.approx(1.0, abs=1e-6)
    ys, xs = np.nonzero(kernel > 1e-6)
    assert set(xs) == {kernel.shape[1] // 2} and ys.max() - ys.min() == 10  # 9 px between half-pixel ends
    rows = np.arange(kernel.shape[0]) - kernel.shape[0] // 2
    assert (kernel.sum(1) * rows**2).sum() == pytest.approx(81 / 12, rel=0.05)  # a box's variance, L^2 / 12


def _moments(kernel: np.ndarray) -> np.ndarray:
    """Second moments (xx, xy, yy) of a centred kernel."""
    y, x = np.mgrid[: kernel.shape[0], : kernel.shape[1]] - kernel.shape[0] // 2
    return np.array([(kernel * x * x).sum(), (kernel * x * y).sum(), (kernel * y * y).sum()])


@pytest.mark.parametrize(("length", "angle"), [(8.0, 0.0), (11.0, 0.7), (6.0, 2.4)])
def test_covariance_is_the_kernels_second_moment(length, angle):
    """Within the bilinear splats' own spread (up to a quarter px^2 per axis: a splat at fraction ``f`` adds
    ``f (1 - f)``)."""
    np.testing.assert_allclose(streak_covariance([(length, angle)]), _moments(streak_kernel(length, angle)), atol=0.25)


def test_a_chain_adds_covariances_and_the_change_is_the_largest_eigenvalue():
    chain = [(8.0, 0.3), (5.0, 1.9)]
    impulse = np.zeros((41, 41), np.float32)
    impulse[20, 20] = 1
    both = streak_blur(streak_blur(impulse, *chain[0]), *chain[1])  # the kernel of the chain
    np.testing.assert_allclose(streak_covariance(chain), _moments(both), atol=0.5)  # two kernels' splats
    other = [(12.0, 1.0)]
    (axx, axy, ayy), (bxx, bxy, byy) = streak_covariance(chain), streak_covariance(other)
    expected = np.abs(np.linalg.eigvalsh([[axx - bxx, axy - bxy], [axy - bxy, ayy - byy]])).max()
    assert streak_change(chain, other) == pytest.approx(expected, rel=1e-12)
    assert streak_change([], []) == 0.0 and streak_change([(6.0, 0.5)], []) == pytest.approx(3.0)


def test_blurring_an_impulse_gives_the_kernel():
    impulse = np.zeros((31, 31), np.float32)
    impulse[15, 15] = 1
    kernel = streak_kernel(7.5, 0.4)
    r = kernel.shape[0] // 2
    np.testing.assert_allclose(streak_blur(impulse, 7.5, 0.4)[15 - r : 16 + r, 15 - r : 16 + r], kernel, atol=1e-7)


def test_a_streak_stands_out_in_one_direction_only_and_off_the_block_lattice():
    assert streak_found(9.0, 0.6, -14.0, -3.0, -10.0)
    assert streak_found(7.0, 0.0, -14.0, -3.0, -10.0)  # horizontal, off the lattice
    assert not streak_found(9.0, 0.6, -8.0, -3.0, -10.0)  # not low enough
    assert not streak_found(9.0, 0.6, -22.0, -10.6, -10.0)  # a rival direction as deep: a compression block grid
    for length, angle in ((16.1, 0.0), (8.02, math.pi / 2), (16.0, math.pi), (8 * math.sqrt(2), math.pi / 4)):
        assert not streak_found(length, angle, -14.0, -4.7, -10.0)  # on the 8 px lattice
        assert not streak_found(length, angle, -14.0, -4.7, -10.0, block_grid=1.3)  # a JPEG's block grid shows
        assert streak_found(length, angle, -14.0, -4.7, -10.0, block_grid=1.0)  # none: the minimum is the streak's


def test_without_a_block_grid_a_rival_may_reach_half_the_score():
    """A directional texture (waves) holds a rival below half the threshold: without a block grid the streak
    still counts while the rival stays above half of its score; with a grid (or none measured) the rival must stay
    above half the threshold."""
    assert streak_found(9.9, 1.56, -16.2, -5.4, -10.0, block_grid=1.02)
    assert not streak_found(9.9, 1.56, -16.2, -5.4, -10.0, block_grid=1.3)
    assert not streak_found(9.9, 1.56, -16.2, -5.4, -10.0)  # no block grid measured: assume one
    assert not streak_found(9.9, 1.56, -16.2, -8.2, -10.0, block_grid=1.02)  # a rival deeper than half the score


def test_a_streak_of_the_previous_frame_continues_at_half_the_threshold():
    """Hysteresis: a weaker reading (score -8, 6 below the rival) is a streak only where the previous frame had
    one in about the same direction (within 20 degrees, directions modulo pi); at least half the threshold in
    score and in lead over the rival, and the rival and lattice tests still hold."""
    weak = (9.0, 0.6, -8.0, -2.0, -10.0)
    assert not streak_found(*weak)  # no streak before: a weak reading does not start one
    assert streak_found(*weak, previous=(7.5, 0.6 + math.radians(19)))
    assert not streak_found(*weak, previous=(7.5, 0.6 + math.radians(21)))  # turned too far
    assert streak_found(9.0, 0.05, -8.0, -2.0, -10.0, previous=(7.5, math.pi - 0.05))  # the same line, 0.1 rad
    assert not streak_found(9.0, 0.6, -8.0, -4.0, -10.0, previous=(7.5, 0.6))  # a lead of 4 over the rival
    assert not streak_found(9.0, 0.6, -4.9, 2.0, -10.0, previous=(7.5, 0.6))  # a score above -5
    assert not streak_found(9.0, 0.6, -14.0, -5.5, -10.0, previous=(7.5, 0.6))  # a rival below -5: a block grid
    assert not streak_found(16.1, 0.0, -8.0, -2.0, -10.0, previous=(16.0, 0.0))  # on the lattice (grid assumed)
    assert streak_found(16.1, 0.0, -8.0, -2.0, -10.0, block_grid=1.0, previous=(16.0, 0.0))


def test_quarters_cover_the_frame_and_refuse_small_ones():
    frame = np.arange(130 * 141).reshape(130, 141)
    quarters = quarter_slices(*frame.shape)
    assert [frame[r, c].shape for r, c in quarters] == [(65, 70)] * 4
    assert frame[quarters[3]][-1, -1] == frame[129, 139] and frame[quarters[0]][0, 0] == frame[0, 0]
    assert quarter_slices(2 * MIN_QUARTER - 1, 500) is None and quarter_slices(2 * MIN_QUARTER, 2 * MIN_QUARTER)


def test_a_uniform_streak_ends_near_the_frames_in_every_quarter():
    """Ends compared by hand: (9, 0.6) ends at (7.43, 5.08); a reading 1 px off, the reversed streak and a
    reading at 1.9 px pass, one quarter 2.3 px off or sharp (another direction) fails."""
    assert streak_uniform((9.0, 0.6), [(9.0, 0.6), (10.0, 0.6), (9.0, 0.6 + math.pi), (8.0, 0.45)])
    assert math.hypot(8 * math.cos(0.45) - 9 * math.cos(0.6), 8 * math.sin(0.45) - 9 * math.sin(0.6)) < 2
    assert not streak_uniform((9.0, 0.6), [(9.0, 0.6), (9.0, 0.6), (9.0, 0.6), (9.0, 0.6 + 0.26)])  # 2.3 px
    assert not streak_uniform((9.0, 0.6), [(9.0, 0.6), (9.0, 0.6), (9.0, 0.6), (21.0, 2.1)])


def test_bad_input():
    with pytest.raises(InputError, match="streak"):
        streak_kernel(-1.0, 0.0)
    with pytest.raises(InputError, match="streak"):
        streak_kernel(5.0, math.nan)
    with pytest.raises(InputError, match=r"\(H, W\)"):
        streak_blur(np.zeros((4, 4, 3)), 5.0, 0.0)


def test_streaks_matched_asks_for_uniformity_only_between_the_limits():
    """Beyond ``streak_match`` (4) or within ``blur_match`` (2) the answer is fixed and the quarters are not read;
    in between a uniform streak is matched (beyond ``blur_match``) and a partial one is not."""
    asked = []

    def uniform(answer):
        return lambda: asked.append(answer) or answer

    assert not streaks_matched(1.5, 4.0, 2.0, uniform(True)) and streaks_matched(4.5, 4.0, 2.0, uniform(False))
    assert asked == []
    assert streaks_matched(3.0, 4.0, 2.0, uniform(True)) and not streaks_matched(3.0, 4.0, 2.0, uniform(False))
    assert asked == [True, False]
