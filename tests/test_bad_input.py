"""The bad-input matrix: every ``infer.py`` command, ``train.py`` and the export commands, each given every kind of
bad input that applies (missing path, empty file, truncated or corrupt file, wrong size, NaN or infinite values, a
checkpoint of another model, an ONNX folder of another task, an output folder that cannot be written). Each case must
end with exactly one error line on stderr naming the input, exit code 2, no traceback, and nothing written where the
output was to go. ``docs/bad_input.md`` lists the matrix."""

import importlib
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from data.vos.io import write_mask
from data.vos.synthetic import synthetic_video
from data.world.dem import generate_archipelago, save_dem
from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem
from models.vos.lit import FRTMSegmentation
from tests.cli.test_triangulate import write_bundler
from tests.models.test_checkpoint import save_checkpoint

SMALL_FINDER = {"backbone": "resnet18", "stage": "layer2", "heads": 2, "head_channels": 8, "channels": 16}
TINY_FRTM = {"mdim": 8, "tracker": {"channels": 8, "num_aug": 2, "memory_size": 4, "init_schedule": [2],
                                    "update_schedule": [2]}}


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    """Good and bad inputs, by name (paths as strings)."""
    root = tmp_path_factory.mktemp("inputs")
    f = {"root": str(root), "missing": str(root / "missing")}
    (root / "empty.bin").write_bytes(b"")
    f["empty"] = str(root / "empty.bin")
    (root / "garbage.png").write_bytes(b"\x89PNG this is not an image at all")
    f["corrupt_png"] = str(root / "garbage.png")
    (root / "garbage.tif").write_bytes(b"II*\x00 not a GeoTIFF")
    f["corrupt_tif"] = str(root / "garbage.tif")
    (root / "a_file").write_text("x")
    f["unwritable"] = str(root / "a_file" / "sub")  # a folder below a regular file cannot be created
    # triangulation
    write_bundler(root / "cube.out")
    f["cube"] = str(root / "cube.out")
    text = (root / "cube.out").read_text()
    (root / "truncated.out").write_text(text[: len(text) // 2])
    f["truncated_out"] = str(root / "truncated.out")
    (root / "garbage.out").write_text("# Bundle file v0.3\nnot numbers at all\n")
    f["corrupt_out"] = str(root / "garbage.out")
    lines = text.splitlines()
    lines[-3] = "nan nan nan"  # a point position of the last track
    (root / "nan.out").write_text("\n".join(lines) + "\n")
    f["nan_out"] = str(root / "nan.out")
    # panoramas and DEMs
    pano = (np.random.default_rng(0).random((32, 256, 3)) * 255).astype(np.uint8)
    cv2.imwrite(str(root / "pano.png"), pano)
    f["pano"] = str(root / "pano.png")
    cv2.imwrite(str(root / "square.png"), pano[:, :32])
    f["square_png"] = str(root / "square.png")
    png = (root / "pano.png").read_bytes()
    (root / "truncated.png").write_bytes(png[: len(png) // 3])
    f["truncated_png"] = str(root / "truncated.png")
    dem = generate_archipelago(size_m=600, cell=10, seed=5, feature_scale_m=300, land_fraction=0.2, forest_height=0)
    save_dem(root / "dem.tif", dem)
    f["dem"] = str(root / "dem.tif")
    z = dem.z.copy()
    z[3, 4] = np.inf  # NaN is nodata (sea); an infinite height is a broken file
    np.savez(root / "inf_dem.npz", z=z, transform=np.array([dem.x0, dem.cell, dem.y0]), crs="")
    f["inf_dem"] = str(root / "inf_dem.npz")
    # point tracking
    frames = root / "frames"
    frames.mkdir()
    for t in range(3):
        cv2.imwrite(str(frames / f"{t:03d}.png"), (np.random.default_rng(t).random((48, 64)) * 255).astype(np.uint8))
    f["frames"] = str(frames)
    (root / "no_frames").mkdir()
    f["no_frames"] = str(root / "no_frames")
    mixed = root / "mixed_frames"
    shutil.copytree(frames, mixed)
    cv2.imwrite(str(mixed / "003.png"), np.zeros((40, 64), np.uint8))
    f["mixed_frames"] = str(mixed)
    broken = root / "broken_frames"
    shutil.copytree(frames, broken)
    (broken / "001.png").write_bytes(b"\x89PNG broken")
    f["broken_frames"] = str(broken)
    small = root / "small_frames"  # below the 16 px a side of the DCF trackers' pyramid and blur profile
    small.mkdir()
    for t in range(2):
        cv2.imwrite(str(small / f"{t:03d}.png"), (np.random.default_rng(t).random((12, 12)) * 255).astype(np.uint8))
    f["small_frames"] = str(small)
    (root / "garbage.mp4").write_bytes(b"not a video at all")
    f["corrupt_video"] = str(root / "garbage.mp4")
    np.save(root / "centre_point.npy", np.array([[6.0, 6.0]]))
    f["centre_point"] = str(root / "centre_point.npy")
    np.save(root / "nan_points.npy", np.array([[10.0, 10.0], [np.nan, 5.0]]))
    f["nan_points"] = str(root / "nan_points.npy")
    np.save(root / "points3.npy", np.ones((4, 3)))
    f["points3"] = str(root / "points3.npy")
    # video object segmentation
    video, labels = synthetic_video(2, n_frames=3, height=48, width=64, n_objects=1)
    vdir = root / "video"
    vdir.mkdir()
    for t, frame in enumerate(video):
        cv2.imwrite(str(vdir / f"{t:05d}.jpg"), (frame.permute(1, 2, 0).numpy()[..., ::-1] * 255).astype(np.uint8))
    f["video"] = str(vdir)
    write_mask(root / "mask.png", labels[0])
    f["mask"] = str(root / "mask.png")
    write_mask(root / "empty_mask.png", torch.zeros_like(labels[0]))
    f["empty_mask"] = str(root / "empty_mask.png")
    write_mask(root / "small_mask.png", labels[0, :40])
    f["small_mask"] = str(root / "small_mask.png")
    vbroken = root / "video_broken"
    shutil.copytree(vdir, vbroken)
    (vbroken / "00001.jpg").write_bytes(b"\xff\xd8 broken")
    f["video_broken"] = str(vbroken)
    # checkpoints
    torch.manual_seed(0)
    save_checkpoint(FRTMSegmentation(**TINY_FRTM), root / "frtm.ckpt")
    f["frtm_ckpt"] = str(root / "frtm.ckpt")
    save_checkpoint(HorizonFinderSystem(**SMALL_FINDER), root / "finder.ckpt")
    f["finder_ckpt"] = str(root / "finder.ckpt")
    save_checkpoint(HorizonSegmenterSystem(**SMALL_FINDER), root / "segmenter.ckpt")
    f["segmenter_ckpt"] = str(root / "segmenter.ckpt")
    (root / "garbage.ckpt").write_bytes(b"PK\x03\x04 not a zip")
    f["corrupt_ckpt"] = str(root / "garbage.ckpt")
    (root / "other_task_onnx").mkdir()
    (root / "other_task_onnx" / "matcher.onnx").write_bytes(b"")
    f["other_task_onnx"] = str(root / "other_task_onnx")
    # localisation
    from models.horizon.filter_bank import BankSettings, build_filter_bank

    build_filter_bank(dem, BankSettings(spacing=100, bins=64, max_range=300, neighbourhood=0), root / "bank",
                      storage_dtype="float32", progress=False)
    f["bank"] = str(root / "bank")
    corrupt_bank = root / "corrupt_bank"
    shutil.copytree(root / "bank", corrupt_bank)
    (corrupt_bank / "bank.json").write_text("{ not json")
    f["corrupt_bank"] = str(corrupt_bank)
    np.save(root / "nan_profiles.npy", np.full((2, 64), np.nan))
    f["nan_profiles"] = str(root / "nan_profiles.npy")
    np.save(root / "short_profiles.npy", np.zeros((2, 60)))
    f["short_profiles"] = str(root / "short_profiles.npy")
    (root / "compass.csv").write_text("compass_deg\n10\n20\n")
    f["compass"] = str(root / "compass.csv")
    (root / "bad_compass.csv").write_text("compass_deg\nten\n")
    f["bad_compass"] = str(root / "bad_compass.csv")
    (root / "bad.yaml").write_text("model: [unclosed\n")
    f["bad_yaml"] = str(root / "bad.yaml")
    return f


TRI = ["triangulate", "--bundler"]
LABEL = ["horizon-label", "--position", "300", "300", "--compass", "0"]
HORIZON = ["horizon", "--image", "{pano}", "--input-width", "256"]
SEGMENT = ["segment", "--out", "{out}"]
BANK = ["build-bank", "--spacing", "100", "--bins", "64", "--max-range", "300", "--out", "{out}"]
FINDER_CONFIG = "configs/demo/horizon_finder.yaml"
HORIZON_EXPORT = ["--finder", "{finder_ckpt}", "--segmenter"]

#: (case id, program, argv, what the error line must name)
CASES = [
    ("triangulate/missing", "infer", [*TRI, "{missing}.out"], "{missing}.out"),
    ("triangulate/empty", "infer", [*TRI, "{empty}"], "{empty}"),
    ("triangulate/corrupt", "infer", [*TRI, "{corrupt_out}"], "{corrupt_out}"),
    ("triangulate/truncated", "infer", [*TRI, "{truncated_out}"], "{truncated_out}"),
    ("triangulate/nan", "infer", [*TRI, "{nan_out}"], "{nan_out}"),
    ("triangulate/bal-missing", "infer", ["triangulate", "--bal", "{missing}.txt"], "{missing}.txt"),
    ("triangulate/unwritable-out", "infer", [*TRI, "{cube}", "--out", "{unwritable}/p.ply"], "{unwritable}"),
    ("render-dataset/missing-dem", "infer", ["render-dataset", "--dem", "{missing}.tif", "--out", "{out}"],
     "{missing}.tif"),
    ("render-dataset/corrupt-dem", "infer", ["render-dataset", "--dem", "{corrupt_tif}", "--out", "{out}"],
     "{corrupt_tif}"),
    ("render-dataset/inf-dem", "infer", ["render-dataset", "--dem", "{inf_dem}", "--out", "{out}"], "{inf_dem}"),
    ("render-dataset/unwritable-out", "infer", ["render-dataset", "--count", "2", "--width", "128", "--height",
                                                "16", "--dem-size", "600", "--dem-cell", "10", "--out",
                                                "{unwritable}"], "{unwritable}"),
    ("horizon-label/missing-image", "infer", [*LABEL, "--image", "{missing}.png", "--dem", "{dem}"],
     "{missing}.png"),
    ("horizon-label/corrupt-image", "infer", [*LABEL, "--image", "{corrupt_png}", "--dem", "{dem}"],
     "{corrupt_png}"),
    ("horizon-label/truncated-image", "infer", [*LABEL, "--image", "{truncated_png}", "--dem", "{dem}"],
     "{truncated_png}"),
    ("horizon-label/wrong-size", "infer", [*LABEL, "--image", "{square_png}", "--dem", "{dem}"], "{square_png}"),
    ("horizon-label/missing-dem", "infer", [*LABEL, "--image", "{pano}", "--dem", "{missing}.tif"],
     "{missing}.tif"),
    ("horizon-label/corrupt-dem", "infer", [*LABEL, "--image", "{pano}", "--dem", "{corrupt_tif}"],
     "{corrupt_tif}"),
    ("horizon-label/inf-dem", "infer", [*LABEL, "--image", "{pano}", "--dem", "{inf_dem}"], "{inf_dem}"),
    ("horizon/other-model-ckpt", "infer", [*HORIZON, "--finder", "{frtm_ckpt}", "--segmenter", "{frtm_ckpt}"],
     "{frtm_ckpt}"),
    ("horizon/corrupt-ckpt", "infer", [*HORIZON, "--finder", "{corrupt_ckpt}", "--segmenter", "{frtm_ckpt}"],
     "{corrupt_ckpt}"),
    ("horizon/missing-ckpt", "infer", [*HORIZON, "--finder", "{missing}.ckpt", "--segmenter", "{frtm_ckpt}"],
     "{missing}.ckpt"),
    ("horizon/empty-onnx", "infer", [*HORIZON, "--finder", "{other_task_onnx}/matcher.onnx", "--segmenter",
                                     "{frtm_ckpt}"], "{other_task_onnx}/matcher.onnx"),
    ("horizon/wrong-size-image", "infer", ["horizon", "--image", "{square_png}", "--finder", "{finder_ckpt}",
                                           "--segmenter", "{finder_ckpt}"], "{square_png}"),
    ("track/missing-frames", "infer", ["track", "--frames", "{missing}", "--detect", "5", "--out", "{out}.npz"],
     "{missing}"),
    ("track/no-frames", "infer", ["track", "--frames", "{no_frames}", "--detect", "5", "--out", "{out}.npz"],
     "{no_frames}"),
    ("track/corrupt-frame", "infer", ["track", "--frames", "{broken_frames}", "--detect", "5", "--out",
                                      "{out}.npz"], "001.png"),
    ("track/frame-sizes-differ", "infer", ["track", "--frames", "{mixed_frames}", "--detect", "5", "--out",
                                           "{out}.npz"], "003.png"),
    ("track/corrupt-video", "infer", ["track", "--frames", "{corrupt_video}", "--detect", "5", "--out",
                                      "{out}.npz"], "{corrupt_video}"),
    ("track/frames-too-small", "infer", ["track", "--frames", "{small_frames}", "--points", "{centre_point}",
                                         "--out", "{out}.npz"], "frame 0"),
    ("track/nan-points", "infer", ["track", "--frames", "{frames}", "--points", "{nan_points}", "--out",
                                   "{out}.npz"], "{nan_points}"),
    ("track/points-wrong-shape", "infer", ["track", "--frames", "{frames}", "--points", "{points3}", "--out",
                                           "{out}.npz"], "{points3}"),
    ("track/unwritable-out", "infer", ["track", "--frames", "{frames}", "--detect", "5", "--method", "klt",
                                       "--out", "{unwritable}/t.npz"], "{unwritable}"),
    ("segment/missing-mask", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{missing}.png", "--ckpt",
                                       "{frtm_ckpt}"], "{missing}.png"),
    ("segment/empty-mask", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{empty_mask}", "--ckpt",
                                     "{frtm_ckpt}"], "{empty_mask}"),
    ("segment/wrong-size-mask", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{small_mask}", "--ckpt",
                                          "{frtm_ckpt}"], "{small_mask}"),
    ("segment/corrupt-frame", "infer", [*SEGMENT, "--video", "{video_broken}", "--mask", "{mask}", "--ckpt",
                                        "{frtm_ckpt}"], "00001.jpg"),
    ("segment/other-model-ckpt", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{mask}", "--ckpt",
                                           "{finder_ckpt}"], "{finder_ckpt}"),
    ("segment/corrupt-ckpt", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{mask}", "--ckpt",
                                       "{corrupt_ckpt}"], "{corrupt_ckpt}"),
    ("segment/other-task-onnx", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{mask}", "--onnx",
                                          "{other_task_onnx}"], "{other_task_onnx}"),
    ("segment/missing-davis", "infer", [*SEGMENT, "--davis", "{missing}", "--ckpt", "{frtm_ckpt}"], "{missing}"),
    ("segment/zero-max-frames", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{mask}", "--ckpt",
                                          "{frtm_ckpt}", "--max-frames", "0"], "--max-frames"),
    ("segment/unwritable-out", "infer", ["segment", "--video", "{video}", "--mask", "{mask}", "--ckpt",
                                         "{frtm_ckpt}", "--out", "{unwritable}"], "{unwritable}"),
    ("build-bank/missing-dem", "infer", [*BANK, "--dem", "{missing}.tif"], "{missing}.tif"),
    ("build-bank/empty-dem", "infer", [*BANK, "--dem", "{empty}"], "{empty}"),
    ("build-bank/corrupt-dem", "infer", [*BANK, "--dem", "{corrupt_tif}"], "{corrupt_tif}"),
    ("build-bank/inf-dem", "infer", [*BANK, "--dem", "{inf_dem}"], "{inf_dem}"),
    ("build-bank/unwritable-out", "infer", ["build-bank", "--dem", "{dem}", "--spacing", "100", "--out",
                                            "{unwritable}"], "{unwritable}"),
    ("localize/missing-bank", "infer", ["localize", "--bank", "{missing}", "--profiles", "{nan_profiles}",
                                        "--out", "{out}.csv"], "{missing}"),
    ("localize/corrupt-bank", "infer", ["localize", "--bank", "{corrupt_bank}", "--profiles", "{nan_profiles}",
                                        "--out", "{out}.csv"], "{corrupt_bank}"),
    ("localize/nan-profiles", "infer", ["localize", "--bank", "{bank}", "--profiles", "{nan_profiles}",
                                        "--compass", "{compass}", "--out", "{out}.csv"], "{nan_profiles}"),
    ("localize/wrong-size-profiles", "infer", ["localize", "--bank", "{bank}", "--profiles", "{short_profiles}",
                                               "--compass", "{compass}", "--out", "{out}.csv"], "{short_profiles}"),
    ("localize/corrupt-compass", "infer", ["localize", "--bank", "{bank}", "--images", "{frames}", "--compass",
                                           "{bad_compass}", "--out", "{out}.csv"], "{bad_compass}"),
    ("localize/other-task-onnx", "infer", ["localize", "--bank", "{bank}", "--images", "{frames}", "--compass",
                                           "{compass}", "--onnx", "{other_task_onnx}", "--out", "{out}.csv"],
     "{other_task_onnx}"),
    ("train/missing-config", "train", ["test", "--config", "{missing}.yaml"], "{missing}.yaml"),
    ("train/corrupt-config", "train", ["test", "--config", "{bad_yaml}"], "{bad_yaml}"),
    ("train/missing-ckpt", "train", ["test", "--config", FINDER_CONFIG, "--ckpt_path", "{missing}.ckpt"],
     "{missing}.ckpt"),
    ("train/corrupt-ckpt", "train", ["test", "--config", FINDER_CONFIG, "--ckpt_path", "{corrupt_ckpt}"],
     "{corrupt_ckpt}"),
    ("train/other-model-ckpt", "train", ["test", "--config", FINDER_CONFIG, "--ckpt_path", "{frtm_ckpt}"],
     "{frtm_ckpt}"),
    ("export.vos_onnx/other-model-ckpt", "export.vos_onnx", ["--ckpt", "{finder_ckpt}", "--out", "{out}"],
     "{finder_ckpt}"),
    ("export.vos_onnx/missing-ckpt", "export.vos_onnx", ["--ckpt", "{missing}.ckpt", "--out", "{out}"],
     "{missing}.ckpt"),
    ("export.vos_onnx/unwritable-out", "export.vos_onnx", ["--ckpt", "{frtm_ckpt}", "--out", "{unwritable}"],
     "{unwritable}"),
    ("export.horizon_onnx/other-model-ckpt", "export.horizon_onnx", [*HORIZON_EXPORT, "{frtm_ckpt}", "--out",
                                                                     "{out}"], "{frtm_ckpt}"),
    ("export.horizon_onnx/corrupt-ckpt", "export.horizon_onnx", [*HORIZON_EXPORT, "{corrupt_ckpt}", "--out",
                                                                 "{out}"], "{corrupt_ckpt}"),
    ("export.horizon_onnx/unwritable-out", "export.horizon_onnx", [*HORIZON_EXPORT, "{segmenter_ckpt}", "--out",
                                                                   "{unwritable}/bundle"], "{unwritable}"),
    ("export.horizon_onnx/bad-frequencies", "export.horizon_onnx", [*HORIZON_EXPORT, "{segmenter_ckpt}", "--bins",
                                                                    "64", "--frequencies", "99", "--out", "{out}"],
     "--frequencies"),
    ("export.tracking_onnx/unwritable-out", "export.tracking_onnx", ["--out", "{unwritable}/bundle"],
     "{unwritable}"),
    ("export.tracking_onnx/not-a-bundle-folder", "export.tracking_onnx", ["--out", "{root}"], "{root}"),
    ("export.tracking_onnx/zero-workers", "export.tracking_onnx", ["--out", "{out}", "--workers", "0"], "--workers"),
    ("export.triangulation/unwritable-out", "export.triangulation", ["--out", "{unwritable}/bundle"],
     "{unwritable}"),
]


def run_program(program: str, argv: list[str]) -> int:
    if program == "infer":
        from cli import main
    elif program == "train":
        from train import run as main
    else:
        main = importlib.import_module(program).main
    try:
        return main(argv)
    except SystemExit as exit_:  # argparse errors
        return exit_.code


def check_one_line_and_exit_2(files, tmp_path, capsys, case, program, argv, names) -> None:
    """Run ``program argv`` (placeholders filled from ``files``) and check the one error line, exit code 2 and
    that nothing was written."""
    values = {**files, "out": str(tmp_path / "out" / "result")}
    argv = [a.format(**values) for a in argv]
    code = run_program(program, argv)
    err = capsys.readouterr().err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert code == 2, f"{case}: exit code {code}, stderr:\n{err[-3000:]}"
    assert "Traceback" not in err, err[-3000:]
    assert lines and "error:" in lines[-1] and names.format(**values) in lines[-1], lines[-3:]
    assert sum("error:" in line for line in lines) == 1, lines
    assert not [p for p in (tmp_path / "out").rglob("*") if p.is_file()], case
    assert not list(Path(files["root"]).rglob("*.partial*")), case


@pytest.mark.parametrize(("case", "program", "argv", "names"), CASES, ids=[c[0] for c in CASES])
def test_bad_input_ends_in_one_line_and_exit_2(files, tmp_path, capsys, case, program, argv, names) -> None:
    check_one_line_and_exit_2(files, tmp_path, capsys, case, program, argv, names)


@pytest.fixture(scope="module")
def bundles(files, tmp_path_factory, triangulation_bundle, tracking_bundle, horizon_setup, vos_setup) -> dict:
    """The exported bundles, and broken copies: a graph missing, a graph changed, a bank of other bins."""
    root = tmp_path_factory.mktemp("bundles")
    b = {"tri_bundle": str(triangulation_bundle), "track_bundle": str(tracking_bundle),
         "horizon_bundle": str(horizon_setup["bundle"]), "vos_bundle": str(vos_setup["bundle"]),
         "horizon_bank": str(horizon_setup["bank"])}
    for task, source, graph in (("tri", triangulation_bundle, "dogleg_step.onnx"), ("vos", vos_setup["bundle"],
                                                                              "frame.onnx")):
        missing = shutil.copytree(source, root / f"{task}_missing")
        (missing / graph).unlink()
        changed = shutil.copytree(source, root / f"{task}_changed")
        data = bytearray((changed / graph).read_bytes())
        data[len(data) // 2] ^= 1
        (changed / graph).write_bytes(bytes(data))
        b[f"{task}_missing"], b[f"{task}_changed"] = str(missing), str(changed)
    bank = shutil.copytree(horizon_setup["bank"], root / "bank128")
    (bank / "bank.json").write_text((bank / "bank.json").read_text().replace('"bins": 64', '"bins": 128'))
    b["bank128"] = str(bank)
    pano = np.zeros((64, 512, 3), np.uint8)
    cv2.imwrite(str(root / "pano512.png"), pano)
    b["pano512"] = str(root / "pano512.png")
    (root / "images").mkdir()
    cv2.imwrite(str(root / "images" / "a.png"), pano)
    (root / "compass.csv").write_text("image,compass_deg\na.png,10\n")
    b["images512"], b["compass512"] = str(root / "images"), str(root / "compass.csv")
    return {**files, **b}


RT_TRI = ["runtime.triangulation", "--bundler", "{cube}", "--bundle"]
RT_TRACK = ["runtime.tracking", "--frames", "{frames}", "--detect", "5", "--out", "{out}.npz", "--bundle"]
RT_VOS = ["runtime.vos", "--video", "{video}", "--mask", "{mask}", "--out", "{out}", "--bundle"]
#: (case id, program, argv, what the error line must name): bundles of another task, a graph missing or changed,
#: inputs that do not fit the bundle, for every runtime command and ``infer.py --onnx``.
RUNTIME_CASES = [
    ("runtime.triangulation/other-task-bundle", RT_TRI[0], [*RT_TRI[1:], "{track_bundle}"], "{track_bundle}"),
    ("runtime.triangulation/missing-graph", RT_TRI[0], [*RT_TRI[1:], "{tri_missing}"], "{tri_missing}"),
    ("runtime.triangulation/hash-mismatch", RT_TRI[0], [*RT_TRI[1:], "{tri_changed}"], "{tri_changed}"),
    ("runtime.triangulation/wrong-size", RT_TRI[0], [*RT_TRI[1:], "{tri_bundle}", "--views", "2"], "--views 2"),
    ("runtime.triangulation/not-a-bundle", RT_TRI[0], [*RT_TRI[1:], "{root}"], "{root}"),
    ("runtime.tracking/other-task-bundle", RT_TRACK[0], [*RT_TRACK[1:], "{vos_bundle}"], "{vos_bundle}"),
    ("runtime.tracking/wrong-size", RT_TRACK[0], [*RT_TRACK[1:], "{track_bundle}"], "frame 0"),
    ("runtime.horizon/other-task-bundle", "runtime.horizon", ["--image", "{pano}", "--bundle", "{tri_bundle}"],
     "{tri_bundle}"),
    ("runtime.horizon/wrong-size", "runtime.horizon", ["--image", "{pano512}", "--bundle", "{horizon_bundle}"],
     "{pano512}"),
    ("runtime.localize/other-task-bundle", "runtime.localize", ["--bank", "{horizon_bank}", "--profiles",
                                                                "{nan_profiles}", "--out", "{out}.csv", "--bundle",
                                                                "{vos_bundle}"], "{vos_bundle}"),
    ("runtime.localize/other-bins-bank", "runtime.localize", ["--bank", "{bank128}", "--profiles",
                                                              "{nan_profiles}", "--out", "{out}.csv", "--bundle",
                                                              "{horizon_bundle}"], "{bank128}"),
    ("runtime.localize/wrong-size", "runtime.localize", ["--bank", "{horizon_bank}", "--images", "{images512}",
                                                         "--compass", "{compass512}", "--out", "{out}.csv",
                                                         "--bundle", "{horizon_bundle}"], "a.png"),
    ("runtime.vos/other-task-bundle", RT_VOS[0], [*RT_VOS[1:], "{horizon_bundle}"], "{horizon_bundle}"),
    ("runtime.vos/missing-graph", RT_VOS[0], [*RT_VOS[1:], "{vos_missing}"], "{vos_missing}"),
    ("runtime.vos/hash-mismatch", RT_VOS[0], [*RT_VOS[1:], "{vos_changed}"], "{vos_changed}"),
    ("runtime.vos/wrong-size", RT_VOS[0], ["--video", "{video}", "--mask", "{small_mask}", "--out", "{out}",
                                           "--bundle", "{vos_bundle}"], "{small_mask}"),
    ("triangulate/onnx-other-task", "infer", [*TRI, "{cube}", "--onnx", "{vos_bundle}"], "{vos_bundle}"),
    ("track/onnx-wrong-size", "infer", ["track", "--frames", "{frames}", "--detect", "5", "--out", "{out}.npz",
                                        "--onnx", "{track_bundle}"], "frame 0"),
    ("horizon/onnx-wrong-size", "infer", ["horizon", "--image", "{pano512}", "--onnx", "{horizon_bundle}"],
     "{pano512}"),
    ("segment/onnx-hash-mismatch", "infer", [*SEGMENT, "--video", "{video}", "--mask", "{mask}", "--onnx",
                                             "{vos_changed}"], "{vos_changed}"),
]


@pytest.mark.slow  # uses exported bundles
@pytest.mark.parametrize(("case", "program", "argv", "names"), RUNTIME_CASES, ids=[c[0] for c in RUNTIME_CASES])
def test_bad_bundles_and_inputs_end_in_one_line_and_exit_2(bundles, tmp_path, capsys, case, program, argv,
                                                             names) -> None:
    check_one_line_and_exit_2(bundles, tmp_path, capsys, case, program, argv, names)
