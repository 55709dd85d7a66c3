"""The DAVOS demo part: its distractor-map figure on a tiny untrained system (the whole part runs in
tests/cli/test_demo.py)."""

from PIL import Image

from bench.davos_demo import plot_distractors
from data.vos.composite_datamodule import lookalike_videos
from models.builders import davos_system


def test_distractor_figure_has_a_row_per_object(tmp_path) -> None:
    model = davos_system(backbone="resnet18", weights=None, projection_channels=8, encoding_channels=4, mdim=8,
                         encoder_dims=(4, 8, 8), tracker={"init_iters": 2, "update_iters": 1, "memory_size": 4})
    video = lookalike_videos(1, n_frames=5, height=48, width=64, n_objects=2)[0]
    plot_distractors(model, video, tmp_path / "d.png", columns=3)
    image = Image.open(tmp_path / "d.png")
    assert image.size[1] > image.size[0] / 3  # three rows of panels: frames and two distractor maps
