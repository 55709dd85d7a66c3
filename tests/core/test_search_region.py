"""Search region of mask trackers against a brute-force reference: 8-connected components by a flood fill and
distances to the previous mask as a minimum over all its pixels."""

import math

import numpy as np
import pytest

from core.errors import InputError
from core.search_region import (
    check_search_radius,
    ignore_band,
    main_component,
    outside_search_region,
    unsupported_components,
)


def flood_components(mask: np.ndarray) -> list[set[tuple[int, int]]]:
    """8-connected components of a bool mask, as pixel sets, by a breadth-first flood fill."""
    seen, out = set(), []
    for start in zip(*np.nonzero(mask), strict=True):
        if start in seen:
            continue
        component, queue = set(), [start]
        seen.add(start)
        while queue:
            r, c = queue.pop()
            component.add((r, c))
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    q = (r + dr, c + dc)
                    if 0 <= q[0] < mask.shape[0] and 0 <= q[1] < mask.shape[1] and mask[q] and q not in seen:
                        seen.add(q)
                        queue.append(q)
        out.append(component)
    return out


def reference(labels: np.ndarray, previous: np.ndarray, ids: list[int], radius: float) -> np.ndarray:
    drop = np.zeros((len(ids), *labels.shape), bool)
    for n, obj in enumerate(ids):
        before = np.argwhere(previous == obj)
        components = flood_components(labels == obj)
        if len(before) == 0 or len(components) < 2:
            continue
        reach = radius * math.sqrt(len(before))

        def distance(component: set, before: np.ndarray = before) -> float:
            pixels = np.array(sorted(component), float)
            return float(np.sqrt(((pixels[:, None] - before[None]) ** 2).sum(-1)).min())

        near = [distance(c) <= reach for c in components]
        if any(near):
            for component, keep in zip(components, near, strict=True):
                for pixel in component if not keep else ():
                    drop[(n, *pixel)] = True
    return drop


def random_blobs(rng: np.random.Generator, size: tuple[int, int], ids: list[int], blobs: int) -> np.ndarray:
    labels = np.zeros(size, np.int64)
    for obj in ids:
        for _ in range(blobs):
            r, c = rng.integers(0, size[0]), rng.integers(0, size[1])
            h, w = rng.integers(1, 6, size=2)
            labels[r : r + h, c : c + w] = obj
    return labels


@pytest.mark.parametrize("seed", range(6))
def test_matches_flood_fill_and_brute_force_distances(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ids = [1, 3]
    previous = random_blobs(rng, (40, 56), ids, 2)
    extra = random_blobs(rng, (40, 56), ids, 3)
    labels = np.where(extra > 0, extra, np.roll(previous, 1, axis=1))  # the objects moved, plus new blobs
    for radius in (0.5, 1.0, 2.0):
        ours = outside_search_region(labels, previous, ids, radius)
        assert np.array_equal(ours, reference(labels, previous, ids, radius))
    assert outside_search_region(labels, previous, ids, 0.5).any()  # the draw exercises dropping


@pytest.mark.parametrize("seed", range(4))
def test_main_component_is_the_largest_flood_fill_component(seed: int) -> None:
    rng = np.random.default_rng(seed)
    masks = np.stack([random_blobs(rng, (30, 40), [1], 5) == 1 for _ in range(3)] + [np.zeros((30, 40), bool)])
    expected = np.zeros_like(masks)
    for n, mask in enumerate(masks):
        components = flood_components(mask)
        for pixel in max(components, key=len) if components else ():  # the first largest in scan order
            expected[(n, *pixel)] = True
    assert np.array_equal(main_component(masks), expected)
    assert (masks.sum((1, 2)) > expected.sum((1, 2)))[:3].any()  # the draw has masks of several components
    with pytest.raises(InputError, match="bool"):
        main_component(masks.astype(np.uint8))


def test_distant_distractor_dropped_and_fallbacks() -> None:
    previous = np.zeros((60, 80), np.int64)
    previous[10:20, 10:20] = 1  # area 100: reach 10 px at radius 1
    labels = previous.copy()
    labels[12:22, 13:23] = 1  # the object, moved
    labels[40:50, 60:70] = 1  # a distractor far away
    drop = outside_search_region(labels, previous, [1], 1.0)
    assert drop.shape == (1, 60, 80)
    assert drop[0, 40:50, 60:70].all() and drop[0].sum() == 100
    assert not outside_search_region(labels, previous, [1], 5.0).any()  # in reach at 50 px
    assert not outside_search_region(labels, np.zeros_like(previous), [1], 1.0).any()  # no previous mask
    far = np.zeros_like(labels)
    far[40:50, 40:50] = far[40:50, 60:70] = 1
    assert not outside_search_region(far, previous, [1], 1.0).any()  # nothing near: the object jumped


def test_bad_inputs_are_named() -> None:
    labels = np.zeros((4, 5), np.int64)
    with pytest.raises(InputError, match="one size"):
        outside_search_region(labels, np.zeros((4, 6), np.int64), [1], 1.0)
    for radius in (-1.0, float("nan"), float("inf"), "1.5", True):
        with pytest.raises(InputError, match="search_radius"):
            check_search_radius(radius)
    with pytest.raises(InputError, match="positive radius"):
        outside_search_region(labels, labels, [1], 0.0)


def bilinear_up(score: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Half-pixel-centre bilinear upsampling of (h, w) to ``size``, pixel by pixel (edge samples repeated)."""
    h, w = score.shape
    out = np.zeros(size)
    for r in range(size[0]):
        for c in range(size[1]):
            y = min(max((r + 0.5) * h / size[0] - 0.5, 0), h - 1)
            x = min(max((c + 0.5) * w / size[1] - 0.5, 0), w - 1)
            y0, x0 = int(y), int(x)
            y1, x1 = min(y0 + 1, h - 1), min(x0 + 1, w - 1)
            fy, fx = y - y0, x - x0
            top = (1 - fx) * score[y0, x0] + fx * score[y0, x1]
            bottom = (1 - fx) * score[y1, x0] + fx * score[y1, x1]
            out[r, c] = (1 - fy) * top + fy * bottom
    return out


@pytest.mark.parametrize("seed", range(4))
def test_unsupported_components_match_flood_fill_and_per_pixel_interpolation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ids = [2, 5]
    labels = random_blobs(rng, (40, 56), ids, 4)
    score = rng.random((2, 10, 14)) ** 2  # mostly low: some components lack support
    expected = np.zeros((2, 40, 56), bool)
    for n, obj in enumerate(ids):
        support = bilinear_up(score[n], (40, 56)) > 0.5
        for component in flood_components(labels == obj):
            if not any(support[pixel] for pixel in component):
                for pixel in component:
                    expected[(n, *pixel)] = True
    drop = unsupported_components(labels, score, ids)
    assert np.array_equal(drop, expected)
    assert drop.any() and ((labels[None] == np.array(ids)[:, None, None]) & ~drop).any()  # both cases drawn


def test_unsupported_components_bad_inputs_are_named() -> None:
    with pytest.raises(InputError, match="score support"):
        unsupported_components(np.zeros((4, 5), np.int64), np.zeros((1, 2, 2)), [1, 2])


@pytest.mark.parametrize("seed", range(3))
def test_ignore_band_matches_brute_force_distances(seed: int) -> None:
    rng = np.random.default_rng(seed)
    masks = np.stack([random_blobs(rng, (30, 40), [1], 3) == 1 for _ in range(2)] + [np.zeros((30, 40), bool)])
    pixels = np.argwhere(np.ones((30, 40), bool)).astype(float)
    for width in (0.25, 0.5, 1.0):
        expected = np.zeros_like(masks)
        for n, mask in enumerate(masks):
            inside = np.argwhere(mask).astype(float)
            if len(inside):
                distance = np.sqrt(((pixels[:, None] - inside[None]) ** 2).sum(-1)).min(1).reshape(30, 40)
                expected[n] = ~mask & (distance <= width * math.sqrt(len(inside)))
        band = ignore_band(masks, width)
        assert np.array_equal(band, expected)
        assert band[:2].any() and not band[2].any()
    with pytest.raises(InputError, match="bool"):
        ignore_band(masks.astype(np.uint8), 0.5)
    with pytest.raises(InputError, match="positive width"):
        ignore_band(masks, 0.0)
