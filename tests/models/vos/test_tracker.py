"""FRTM tracker loop on synthetic videos: segmentation quality of the target model alone on slow videos,
late objects, timings and input errors."""

import pytest
import torch

from core.errors import InputError
from data.vos.synthetic import synthetic_video
from models.backbones import ResNetBackbone
from models.vos.decoder import SegmentationDecoder
from models.vos.metrics import evaluate_sequence
from models.vos.target_model import apply_filter
from models.vos.tracker import COMPONENTS, FRTMTracker
from models.vos.tracker_settings import FRTMSettings


@pytest.fixture(scope="module")
def backbone() -> ResNetBackbone:
    torch.manual_seed(0)
    return ResNetBackbone("resnet18", stages=("layer1", "layer2", "layer3", "layer4"))


def small_tracker(backbone, decoder=None, **kw) -> FRTMTracker:
    args = {"channels": 16, "num_aug": 3, "memory_size": 12, "init_schedule": (3, 5), "update_schedule": (5,),
            "update_every": 2}
    return FRTMTracker(backbone, decoder, FRTMSettings(**{**args, **kw}))


def test_target_model_tracks_slow_object_better_than_copying(backbone) -> None:
    frames, labels = synthetic_video(11, n_frames=8, height=96, width=128, n_distractors=0, motion=0.6)
    tracker = small_tracker(backbone)
    pred = torch.stack(list(tracker.segment(frames, {0: labels[0]})))
    assert pred.shape == labels.shape and torch.equal(pred[0], labels[0])
    ours = evaluate_sequence(pred, labels)[1]["J-Mean"]
    copy = evaluate_sequence(labels[:1].expand_as(labels), labels)[1]["J-Mean"]
    assert ours > 0.5 and ours > copy
    assert set(tracker.timings) == set(COMPONENTS) and all(v > 0 for v in tracker.timings.values())


def test_late_object_and_decoder_path(backbone) -> None:
    frames, labels = synthetic_video(4, n_frames=6, height=64, width=96, n_objects=2, n_distractors=0, motion=0.3)
    first = torch.where(labels[0] == 1, 1, 0)
    decoder = SegmentationDecoder(backbone.channels, mdim=8).eval()
    tracker = small_tracker(backbone, decoder)
    with torch.inference_mode():
        pred = torch.stack(list(tracker.segment(frames, {0: first, 3: labels[3]})))
    assert not (pred[:3] == 2).any()
    assert torch.equal(pred[3] == 2, labels[3] == 2) and tracker.ids == [1, 2]
    assert tracker.memory.weights.shape == (2, 12)


def test_flip_test_decodes_the_mirrored_frame_too(backbone) -> None:
    frames, labels = synthetic_video(2, n_frames=4, height=64, width=96, n_distractors=0, motion=0.3)
    decoder = SegmentationDecoder(backbone.channels, mdim=8).eval()
    plain, flipped = small_tracker(backbone, decoder), small_tracker(backbone, decoder, flip_test=True)
    with torch.inference_mode():
        for tracker in (plain, flipped):
            tracker.add_objects(frames[0], labels[0], [1])
        logits, z = plain.segment_frame(frames[1])
        logits_flip, z_flip = flipped.segment_frame(frames[1])
        score = apply_filter(z_flip[:, None], flipped.wf)  # the mirrored frame is decoded with the same score
        mirrored = decoder(score.flip(-1), backbone(frames[1].flip(-1)[None]), (64, 96))[:, 0].flip(-1)
    torch.testing.assert_close(z_flip, z)  # the target model reads the frame itself
    torch.testing.assert_close(logits_flip, (logits + mirrored) / 2, rtol=1e-5, atol=1e-5)
    assert flipped.timings["backbone"] > 0
    # without the decoder the setting changes nothing
    a = small_tracker(backbone, decoder, use_decoder=False)
    b = small_tracker(backbone, decoder, use_decoder=False, flip_test=True)
    with torch.inference_mode():
        preds = [torch.stack(list(t.segment(frames, {0: labels[0]}))) for t in (a, b)]
    assert torch.equal(*preds)


def test_bad_inputs(backbone) -> None:
    frames, labels = synthetic_video(1, n_frames=3, height=48, width=64)
    tracker = small_tracker(backbone)
    with pytest.raises(InputError, match="first frame has no mask"):
        list(tracker.segment(frames, {1: labels[1]}))
    with pytest.raises(InputError, match="empty"):
        list(tracker.segment(frames, {0: torch.zeros_like(labels[0])}))
    with pytest.raises(InputError, match="mask of frame 0"):
        list(tracker.segment(frames, {0: labels[0, :40]}))


def test_optimizer_precision_option(backbone) -> None:
    """float64 fits keep float32 filters and CG state; float32 and float64 runs agree on a short slow video."""
    frames, labels = synthetic_video(11, n_frames=4, height=64, width=96, n_distractors=0, motion=0.3)
    preds = {}
    for dt in ("float32", "float64"):
        tracker = small_tracker(backbone, optimizer_dtype=dt)
        preds[dt] = torch.stack(list(tracker.segment(frames, {0: labels[0]})))
        assert tracker.wf.dtype == tracker.wp.dtype == torch.float32
        assert all(t.dtype == torch.float32 for t in tracker.cg_state[0])
    inter = ((preds["float32"] == 1) & (preds["float64"] == 1)).sum()
    assert inter / ((preds["float32"] == 1) | (preds["float64"] == 1)).sum() > 0.9
    with pytest.raises(InputError, match="optimizer_dtype"):
        small_tracker(backbone, optimizer_dtype="float16")


def test_process_height_runs_the_tracker_at_that_size(backbone) -> None:
    """Frames of 48 x 64 processed at 96 rows: the backbone sees 96 x 128, the masks come back at 48 x 64, the
    first one unchanged, and the object is tracked as well as at the input size (a slow synthetic video)."""
    frames, labels = synthetic_video(11, n_frames=6, height=48, width=64, n_distractors=0, motion=0.6)
    seen = []
    hook = backbone.register_forward_pre_hook(lambda module, args: seen.append(tuple(args[0].shape[-2:])))
    try:
        pred = torch.stack(list(small_tracker(backbone, process_height=96).segment(frames, {0: labels[0]})))
    finally:
        hook.remove()
    assert set(seen) == {(96, 128)}
    assert pred.shape == labels.shape and torch.equal(pred[0], labels[0])
    native = torch.stack(list(small_tracker(backbone).segment(frames, {0: labels[0]})))
    j_up, j_native = (evaluate_sequence(p, labels)[1]["J-Mean"] for p in (pred, native))
    assert j_up > 0.5 and j_up > j_native - 0.1
    with pytest.raises(InputError, match="process_height"):
        FRTMSettings(process_height=-1)


def crafted_frame(tracker: FRTMTracker, logits: torch.Tensor) -> list[torch.Tensor]:
    """Make ``tracker`` segment every frame with the given logits (its features stay its own); returns the list
    that collects the soft masks fed to the memory."""
    segment_frame, update, fed = tracker.segment_frame, tracker.update, []
    tracker.segment_frame = lambda image: (logits.clone(), segment_frame(image)[1])
    tracker.update = lambda soft, z: (fed.append(soft), update(soft, z))[1]
    return fed


def test_search_region_gives_far_components_to_the_background(backbone) -> None:
    """The object moved by a few px and a look-alike blob far away: with ``search_radius`` 1 (reach 10 px from
    the previous 10 x 10 mask) the blob is background in the labels and in the memory's soft masks; without the
    setting it is kept."""
    frames = torch.rand(3, 3, 64, 96, generator=torch.Generator().manual_seed(0))
    first = torch.zeros(64, 96, dtype=torch.long)
    first[10:20, 10:20] = 1
    logits = torch.full((1, 64, 96), -5.0)
    logits[0, 12:22, 13:23] = logits[0, 40:50, 60:70] = 5.0
    moved = torch.zeros_like(first)
    moved[12:22, 13:23] = 1
    for radius, expected in ((1.0, moved), (0.0, (logits[0] > 0).long())):
        tracker = small_tracker(backbone, search_radius=radius, label_stride=1)
        fed = crafted_frame(tracker, logits)
        with torch.inference_mode():
            pred = list(tracker.segment(frames, {0: first}))
        assert all(torch.equal(p, expected) for p in pred[1:])
        assert torch.equal(fed[0][0] > 0.5, expected.bool()) and fed[0][0][expected == 0].max() < 1e-6
    with pytest.raises(InputError, match="search_radius"):
        FRTMSettings(search_radius=-1.0)


def test_memory_main_component_keeps_stray_blobs_out_of_the_memory(backbone) -> None:
    """A small blob near the object survives the search region and stays in the labels; with
    ``memory_main_component`` the memory's labels hold the object's 10 x 10 component only."""
    frames = torch.rand(2, 3, 64, 96, generator=torch.Generator().manual_seed(1))
    first = torch.zeros(64, 96, dtype=torch.long)
    first[10:20, 10:20] = 1
    logits = torch.full((1, 64, 96), -5.0)
    logits[0, 12:22, 13:23] = logits[0, 12:15, 26:29] = 5.0  # the object and a 3 x 3 blob 3 px beside it
    for main, blob_in_memory in ((True, False), (False, True)):
        tracker = small_tracker(backbone, search_radius=1.0, label_stride=1, memory_main_component=main)
        crafted_frame(tracker, logits)
        insert, inserted = tracker.insert_samples, []
        tracker.insert_samples = lambda z, y, *rest, insert=insert, seen=inserted: (
            seen.append(y), insert(z, y, *rest))[1]
        with torch.inference_mode():
            pred = list(tracker.segment(frames, {0: first}))
        assert torch.equal(pred[1], (logits[0] > 0).long())
        assert (inserted[0][0, 12:15, 26:29] > 0.5).all() == blob_in_memory
        assert (inserted[0][0, 12:22, 13:23] > 0.5).all()


def test_keep_first_holds_the_given_mask_in_the_memory(backbone) -> None:
    """Over a video longer than the memory, ``keep_first`` keeps the first frame's slot (its features as fitted on
    the given mask) with at least that share of the weight; without it (the paper's FRTM) the slot is replaced (a
    fast decay, learning rate 0.5, makes it the lightest within the video)."""
    frames, labels = synthetic_video(12, n_frames=10, height=64, width=96, n_distractors=0, motion=0.5)
    for share in (0.3, 0.0):
        tracker = small_tracker(backbone, memory_size=4, learning_rate=0.5, keep_first=share)
        with torch.inference_mode():
            frames_iter = iter(tracker.segment(frames, {0: labels[0]}))
            next(frames_iter)
            first = tracker.memory.features[0, 0].clone()
            list(frames_iter)
        kept = torch.equal(tracker.memory.features[0, 0], first)
        assert kept == (share > 0)
        if share:
            assert float(tracker.memory.weights[0, 0]) >= share - 1e-6


def test_score_support_drops_components_the_target_model_does_not_see(backbone, monkeypatch) -> None:
    """The decoder's mask has the object and a blob; the target model's score is 1 on the object only: with
    ``score_support`` the blob is background in the labels and in the memory; without the setting it is kept."""
    import models.vos.tracker as tracker_module

    frames = torch.rand(3, 3, 64, 96, generator=torch.Generator().manual_seed(2))
    first = torch.zeros(64, 96, dtype=torch.long)
    first[16:32, 16:32] = 1
    logits = torch.full((1, 64, 96), -5.0)
    logits[0, 16:32, 16:32] = logits[0, 40:56, 64:80] = 5.0
    real_filter = tracker_module.apply_filter

    def score_on_the_object(z: torch.Tensor, wf: torch.Tensor) -> torch.Tensor:
        out = torch.zeros_like(real_filter(z, wf))  # (N, K, h, w) at the feature stride
        stride = 64 // out.shape[-2]
        out[..., 16 // stride : 32 // stride, 16 // stride : 32 // stride] = 1
        return out

    monkeypatch.setattr(tracker_module, "apply_filter", score_on_the_object)
    for support, expected in ((True, first), (False, (logits[0] > 0).long())):
        tracker = small_tracker(backbone, score_support=support, label_stride=1)
        fed = crafted_frame(tracker, logits)
        with torch.inference_mode():
            pred = list(tracker.segment(frames, {0: first}))
        assert all(torch.equal(p, expected) for p in pred[1:])
        assert torch.equal(fed[0][0] > 0.5, expected.bool())
    with pytest.raises(InputError, match="score_support"):
        FRTMSettings(score_support="true")


def test_ignore_band_gives_zero_memory_weight_next_to_the_mask(backbone) -> None:
    """With ``ignore_band`` 0.5 the memory slot of frame 1 (a 10 x 10 mask: band 5 px) has pixel weight 0 on the
    pixels outside the mask within 5 px of it (Euclidean, by brute force) and the hinge weights elsewhere; without
    the setting no weight is 0."""
    frames = torch.rand(2, 3, 64, 96, generator=torch.Generator().manual_seed(3))
    first = torch.zeros(64, 96, dtype=torch.long)
    first[20:30, 30:40] = 1
    logits = torch.where(first.bool(), 5.0, -5.0)[None].float()
    rows, cols = torch.meshgrid(torch.arange(64), torch.arange(96), indexing="ij")
    inside = torch.stack(torch.nonzero(first, as_tuple=True), -1).float()  # (A, 2)
    distance = torch.cdist(torch.stack([rows, cols], -1).flatten(0, 1).float(), inside).min(1).values.view(64, 96)
    band = (distance > 0) & (distance <= 5.0)
    for width in (0.5, 0.0):
        tracker = small_tracker(backbone, ignore_band=width, label_stride=1, update_every=100)
        crafted_frame(tracker, logits)
        with torch.inference_mode():
            list(tracker.segment(frames, {0: first}))
        slot = int(tracker.memory.newest[0])
        weights = tracker.memory.pixel_weights[0, slot]
        assert slot > 0 and weights[first.bool()].min() > 0
        assert torch.equal(weights == 0, band if width else torch.zeros_like(band))
        assert weights[~band & ~first.bool()].unique().numel() == 1  # the hinge's background weight
    for width in (-0.5, float("nan")):
        with pytest.raises(InputError, match="ignore_band"):
            FRTMSettings(ignore_band=width)
