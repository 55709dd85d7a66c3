"""``infer.py segment``: a run from a checkpoint writes palette masks; bad input ends in one line, exit 2; a killed
DAVIS run resumes to the same masks and scores."""

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

import infer
from data.vos.io import read_mask, write_mask
from data.vos.synthetic import synthetic_video
from models.vos.lit import FRTMSegmentation
from tests.cli.conftest import kill_and_resume, run_infer, tree_bytes
from tests.models.test_checkpoint import save_checkpoint

TRACKER = {"channels": 8, "num_aug": 2, "memory_size": 6, "init_schedule": [2], "update_schedule": [2]}


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("vos")
    frames, labels = synthetic_video(2, n_frames=4, height=48, width=64, n_objects=2)
    (root / "frames").mkdir()
    for t, f in enumerate(frames):
        Image.fromarray((f.permute(1, 2, 0).numpy() * 255).astype(np.uint8)).save(root / "frames" / f"{t:05d}.jpg")
    write_mask(root / "first.png", labels[0])
    write_mask(root / "small.png", labels[0, :40])
    write_mask(root / "empty.png", torch.zeros_like(labels[0]))
    (root / "broken.jpg").write_bytes(b"\xff\xd8 not really a jpeg")
    torch.manual_seed(0)
    model = FRTMSegmentation(mdim=8, tracker=TRACKER)
    save_checkpoint(model, root / "model.ckpt")
    return root


def test_segment_writes_palette_masks(video: Path, tmp_path: Path) -> None:
    code = infer.main(["segment", "--video", str(video / "frames"), "--mask", str(video / "first.png"),
                       "--ckpt", str(video / "model.ckpt"), "--out", str(tmp_path / "out"),
                       "--overlay", str(tmp_path / "overlay.mp4")])
    assert code == 0
    written = sorted((tmp_path / "out").glob("*.png"))
    assert [p.stem for p in written] == ["00000", "00001", "00002", "00003"]
    assert Image.open(written[1]).mode == "P"
    assert torch.equal(read_mask(written[0]), read_mask(video / "first.png"))
    assert (tmp_path / "overlay.mp4").stat().st_size > 0


def test_max_frames_cuts_the_video(video: Path, davos_ckpt: Path, tmp_path: Path, capsys) -> None:
    """--max-frames 2 writes the first two masks of the whole run (the trackers are causal); a later annotation
    beyond the cut is no error; 0 frames is refused."""
    args = ["segment", "--video", str(video / "frames"), "--mask", str(video / "first.png")]
    (tmp_path / "later").mkdir()
    write_mask(tmp_path / "later" / "00003.png", read_mask(video / "first.png"))
    for ckpt in (video / "model.ckpt", davos_ckpt):
        whole, cut = tmp_path / f"{ckpt.stem}_whole", tmp_path / f"{ckpt.stem}_cut"
        assert infer.main([*args, "--ckpt", str(ckpt), "--out", str(whole)]) == 0
        assert infer.main([*args, "--ckpt", str(ckpt), "--out", str(cut), "--max-frames", "2",
                           "--annotations", str(tmp_path / "later")]) == 0
        assert sorted(p.name for p in cut.iterdir()) == ["00000.png", "00001.png"]
        assert all(torch.equal(read_mask(cut / name), read_mask(whole / name)) for name in ("00000.png", "00001.png"))
    capsys.readouterr()
    assert infer.main([*args, "--ckpt", str(video / "model.ckpt"), "--out", str(tmp_path / "o"), "--max-frames",
                       "0"]) == 2
    assert "--max-frames must be at least 1, got 0" in capsys.readouterr().err and not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "mask, extra, message",
    [
        ("missing.png", [], "does not exist"),
        ("small.png", [], "is (40, 64)"),
        ("empty.png", [], "labels no object"),
        ("first.png", ["--video-broken"], "cannot be read"),
        ("first.png", ["--no-model"], "exactly one of --ckpt"),
    ],
)
def test_bad_input_exits_2(video: Path, tmp_path: Path, capsys, mask: str, extra: list, message: str) -> None:
    frames = video / "frames"
    if "--video-broken" in extra:
        frames = tmp_path / "frames"
        frames.mkdir()
        (frames / "00000.jpg").write_bytes((video / "broken.jpg").read_bytes())
    model = [] if "--no-model" in extra else ["--ckpt", str(video / "model.ckpt")]
    code = infer.main(["segment", "--video", str(frames), "--mask", str(video / mask), *model,
                       "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err


@pytest.fixture(scope="module")
def davis(tmp_path_factory) -> Path:
    """A DAVIS 2017 layout of 6 short synthetic sequences (480p folder names, 48 x 64 px)."""
    root = tmp_path_factory.mktemp("davis")
    names = [f"seq{i}" for i in range(6)]
    for i, name in enumerate(names):
        frames, labels = synthetic_video(20 + i, n_frames=6, height=48, width=64, n_objects=2)
        (root / "JPEGImages" / "480p" / name).mkdir(parents=True)
        for t, f in enumerate(frames):
            Image.fromarray((f.permute(1, 2, 0).numpy() * 255).astype(np.uint8)).save(
                root / "JPEGImages" / "480p" / name / f"{t:05d}.jpg")
            write_mask(root / "Annotations" / "480p" / name / f"{t:05d}.png", labels[t])
    (root / "ImageSets" / "480p").mkdir(parents=True)
    (root / "ImageSets" / "480p" / "val.txt").write_text("\n".join(names) + "\n")
    return root


@pytest.mark.slow
def test_killed_davis_run_resumes_to_the_same_masks_and_scores(video: Path, davis: Path, tmp_path: Path) -> None:
    args = ["segment", "--davis", str(davis), "--split", "val", "--ckpt", str(video / "model.ckpt")]
    run_infer([*args, "--out", str(tmp_path / "whole")])
    hit = kill_and_resume([*args, "--out", str(tmp_path / "killed")], tmp_path / "killed", kills=3, seed=2,
                          max_extra_s=0.5)
    assert hit == 3
    whole = tree_bytes(tmp_path / "whole")
    assert len(whole) == 6 * (6 + 1) + 2 and tree_bytes(tmp_path / "killed") == whole


def test_davis_output_of_another_run_is_refused(video: Path, davis: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    out.mkdir()
    (out / "segment_job.json").write_text('{"model": "another.ckpt"}')
    code = infer.main(["segment", "--davis", str(davis), "--split", "val", "--ckpt", str(video / "model.ckpt"),
                       "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "holds masks of another segmentation run" in err[0]


@pytest.fixture(scope="module")
def davos_ckpt(tmp_path_factory) -> Path:
    from models.builders import davos_system

    path = tmp_path_factory.mktemp("davos") / "davos.ckpt"
    system = davos_system(backbone="resnet18", weights=None, projection_channels=8, encoding_channels=4, mdim=8,
                          encoder_dims=(4, 8, 8), tracker={"init_iters": 2, "update_iters": 1, "memory_size": 4})
    return save_checkpoint(system, path)


def test_davos_checkpoint_segments_ids_that_skip_numbers_and_objects_that_come_later(
        video: Path, davos_ckpt: Path, tmp_path: Path) -> None:
    import cv2

    first = read_mask(video / "first.png")
    skipping = torch.where(first == 2, 3, first)  # ids 1 and 3: tracked and written as 1 and 3
    write_mask(tmp_path / "first.png", torch.where(skipping == 3, 0, skipping))
    (tmp_path / "later").mkdir()
    write_mask(tmp_path / "later" / "00002.png", skipping)  # object 3 starts at frame 2
    code = infer.main(["segment", "--video", str(video / "frames"), "--mask", str(tmp_path / "first.png"),
                       "--annotations", str(tmp_path / "later"), "--ckpt", str(davos_ckpt), "--out",
                       str(tmp_path / "out"), "--overlay", str(tmp_path / "overlay.mp4")])
    assert code == 0
    masks = [read_mask(p) for p in sorted((tmp_path / "out").glob("*.png"))]
    assert set(masks[0].unique().tolist()) <= {0, 1} and 3 not in masks[1].unique().tolist()
    assert torch.equal(masks[2][skipping == 3], skipping[skipping == 3])  # the later mask is taken as given
    assert set(torch.cat([m.unique() for m in masks]).tolist()) <= {0, 1, 3}
    overlay = cv2.VideoCapture(str(tmp_path / "overlay.mp4"))
    assert overlay.get(cv2.CAP_PROP_FRAME_WIDTH) == 2 * 64  # masks and distractor maps side by side
    # a gray (DAVIS 2016) mask is object 1
    Image.fromarray(((first > 0).numpy() * 255).astype(np.uint8), mode="L").save(tmp_path / "gray.png")
    assert infer.main(["segment", "--video", str(video / "frames"), "--mask", str(tmp_path / "gray.png"), "--ckpt",
                       str(davos_ckpt), "--out", str(tmp_path / "gray")]) == 0
    assert set(read_mask(tmp_path / "gray" / "00003.png").unique().tolist()) <= {0, 1}


def test_annotations_named_after_no_frame_are_refused(video: Path, davos_ckpt: Path, tmp_path: Path, capsys) -> None:
    (tmp_path / "later").mkdir()
    write_mask(tmp_path / "later" / "frame9.png", read_mask(video / "first.png"))
    code = infer.main(["segment", "--video", str(video / "frames"), "--mask", str(video / "first.png"),
                       "--annotations", str(tmp_path / "later"), "--ckpt", str(davos_ckpt), "--out",
                       str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "named after no frame" in err[0] and not (tmp_path / "o").exists()


@pytest.mark.slow  # uses an exported bundle
def test_a_bundle_segments_through_the_runtime(video: Path, vos_setup: dict, tmp_path: Path, capsys) -> None:
    from runtime.video_loop import segment_folder as runtime_segment_folder
    from runtime.vos import OnnxFRTMTracker

    args = ["segment", "--video", str(video / "frames"), "--mask", str(video / "first.png"), "--onnx",
            str(vos_setup["bundle"])]
    assert infer.main([*args, "--out", str(tmp_path / "cli")]) == 0
    assert "onnxruntime" in capsys.readouterr().out
    runtime_segment_folder(OnnxFRTMTracker(vos_setup["bundle"]), video / "frames", video / "first.png",
                           tmp_path / "runtime")
    assert tree_bytes(tmp_path / "cli") == tree_bytes(tmp_path / "runtime") and len(tree_bytes(tmp_path / "cli")) == 4
    assert infer.main([*args, "--out", str(tmp_path / "cut"), "--max-frames", "3"]) == 0
    whole, cut = tree_bytes(tmp_path / "cli"), tree_bytes(tmp_path / "cut")
    assert len(cut) == 3 and all(cut[name] == whole[name] for name in cut)
    assert infer.main([*args, "--out", str(tmp_path / "o"), "--overlay", str(tmp_path / "o.mp4")]) == 2
    assert "need --ckpt" in capsys.readouterr().err
