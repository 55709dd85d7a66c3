"""Composite videos: pasting against direct pixel indexing, twins moving with their host, placement rules,
determinism."""

import pytest
import torch

from core.errors import InputError
from data.vos.composites import Paste, compose, composite_video, pingpong, random_pastes


def _video(t: int = 5, h: int = 24, w: int = 32, x0: int = 4, step: int = 2, seed: int = 0):
    """Random frames and a 6x8 block object moving right by ``step`` px per frame."""
    frames = torch.randint(0, 256, (t, 3, h, w), generator=torch.Generator().manual_seed(seed), dtype=torch.uint8)
    labels = torch.zeros(t, h, w, dtype=torch.int64)
    for i in range(t):
        labels[i, 8:14, x0 + step * i : x0 + step * i + 8] = 1
    return frames, labels


def test_pingpong_runs_back_and_forth() -> None:
    assert pingpong(torch.arange(9), 4).tolist() == [0, 1, 2, 3, 2, 1, 0, 1, 2]
    assert pingpong(torch.tensor([-1, 3]), 1).tolist() == [0, 0]


def test_no_paste_is_the_host_and_a_shifted_paste_moves_the_pixels() -> None:
    host, source = _video(seed=1), _video(seed=2, x0=2, step=1)
    frames, labels = compose(host, [source], [], times=[1, 3])
    assert torch.equal(frames, host[0][[1, 3]]) and torch.equal(labels, host[1][[1, 3]])
    paste = Paste(0, 1, offset=1, scale=1.0, flip=False, gain=1.0, centre=(0.0, 0.0), shift=(10.0, 6.0))
    frames, labels = compose(host, [source], [paste])
    for t in range(5):
        src = t + 1 if t + 1 < 5 else 3  # pingpong over 5 frames
        ys, xs = torch.nonzero(source[1][src] == 1, as_tuple=True)
        inner = (ys > ys.min()) & (ys < ys.max()) & (xs > xs.min()) & (xs < xs.max())
        y, x = ys[inner] + 6, xs[inner] + 10
        assert torch.equal(frames[t][:, y, x], source[0][src][:, ys[inner], xs[inner]])
        assert (labels[t][y, x] == 2).all()
        assert ((labels[t] == 2).sum() - (source[1][src] == 1).sum()).abs() <= 4  # only the 4 corners differ


def test_a_twin_moves_with_its_host_and_a_flip_mirrors_it() -> None:
    host = _video(t=6, w=48)
    for flip in (False, True):
        paste = Paste(0, 1, 0, 1.0, flip, 1.0, centre=(8.0, 11.0), shift=(12.0, 6.0))
        _, labels = compose(host, [host], [paste])
        dx = [float(torch.nonzero(labels[t] == 2)[:, 1].float().mean() - torch.nonzero(labels[t] == 1)[:, 1]
                    .float().mean()) for t in range(6)]
        if flip:  # mirrored about x = 8: the twin moves left while the host moves right
            assert dx[-1] < dx[0] - 15
        else:
            assert max(dx) - min(dx) < 1e-6


def test_random_pastes_are_seeded_and_placed_inside_without_covering_the_host() -> None:
    videos = [_video(t=4, h=48, w=64, seed=s) for s in range(3)]
    a = random_pastes(torch.Generator().manual_seed(5), 0, videos, ["twin", "paste"], min_pixels=20)
    b = random_pastes(torch.Generator().manual_seed(5), 0, videos, ["twin", "paste"], min_pixels=20)
    assert a == b and a[0].source == 0 and a[1].source in (1, 2)
    frames, labels = compose(videos[0], videos, a)
    assert set(labels[0].unique().tolist()) == {0, 1, 2, 3}
    host_left = (labels[0] == 1).sum() / (videos[0][1][0] == 1).sum()
    assert host_left >= 0.7  # the host object is mostly still visible
    again = composite_video(torch.Generator().manual_seed(5), 0, videos, ["twin", "paste"], min_pixels=20)
    assert torch.equal(again[0], frames) and torch.equal(again[1], labels)


def test_bad_composites_are_refused() -> None:
    video = _video()
    with pytest.raises(InputError, match="kinds"):
        random_pastes(torch.Generator(), 0, [video], ["clone"])
    with pytest.raises(InputError, match="two videos"):
        random_pastes(torch.Generator(), 0, [video], ["paste"], min_pixels=10)
    with pytest.raises(InputError, match="times"):
        compose(video, [video], [], times=[7])
