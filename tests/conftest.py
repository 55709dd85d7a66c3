"""Shared fixtures: the real data beside the project, skipped cleanly when absent."""

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Root of ``../shared/data``; tests using it are skipped when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data is not present")
    return SHARED_DATA


#: Small horizon networks (stride-8 stage) for the bundle tests.
SMALL_HORIZON = {"backbone": "resnet18", "stage": "layer2", "heads": 2, "head_channels": 8, "channels": 16}


def _randomize_batch_norm(model) -> None:
    """Non-trivial batch-norm statistics, so that untrained networks give varied outputs."""
    import torch

    for module in model.modules():
        if isinstance(module, torch.nn.BatchNorm2d):
            module.running_mean.uniform_(-0.1, 0.1)
            module.running_var.uniform_(0.5, 1.5)


@pytest.fixture(scope="session")
def triangulation_bundle(tmp_path_factory) -> Path:
    """A 3-view triangulation bundle (5 dogleg iterations)."""
    from export.triangulation import export_bundle

    return export_bundle(tmp_path_factory.mktemp("bundles") / "triangulation", views=3, iterations=5)


@pytest.fixture(scope="session")
def tracking_bundle(tmp_path_factory) -> Path:
    """A ccot tracking bundle."""
    from export.tracking_onnx import export_bundle

    return export_bundle(tmp_path_factory.mktemp("bundles") / "tracking", "ccot", height=96, width=128)


@pytest.fixture(scope="session")
def horizon_setup(tmp_path_factory) -> dict:
    """A horizon bundle for 32 x 256 panoramas (networks at 256 px) of small untrained networks (returned too)
    and a filter bank of 64 bins over a small DEM that its matcher fits."""
    import torch

    from data.world.dem import generate_archipelago
    from export.horizon_onnx import export_bundle
    from models.builders import horizon_network
    from models.horizon.filter_bank import BankSettings, build_filter_bank

    root = tmp_path_factory.mktemp("horizon")
    torch.manual_seed(0)
    finder, segmenter = horizon_network("finder", **SMALL_HORIZON), horizon_network("segmenter", **SMALL_HORIZON)
    for net in (finder, segmenter):
        _randomize_batch_norm(net)
    dem = generate_archipelago(size_m=600, cell=10, seed=5, feature_scale_m=300, land_fraction=0.2, forest_height=0)
    settings = BankSettings(spacing=50, bins=64, max_range=300, neighbourhood=0)
    bank = build_filter_bank(dem, settings, root / "bank", storage_dtype="float32", progress=False)
    export_bundle(root / "bundle", finder, segmenter, height=32, width=256, input_width=256, bins=64)
    return {"bundle": root / "bundle", "finder": finder, "segmenter": segmenter, "bank": bank.path, "dem": dem,
            "bank_settings": settings}


@pytest.fixture(scope="session")
def vos_setup(tmp_path_factory) -> dict:
    """A VOS bundle of a small untrained FRTM tracker (returned too; memory labels at half resolution)."""
    import torch

    from export.vos_onnx import export_bundle
    from models.backbones import ResNetBackbone
    from models.vos.decoder import SegmentationDecoder
    from models.vos.tracker import FRTMTracker
    from models.vos.tracker_settings import FRTMSettings

    torch.manual_seed(0)
    backbone = ResNetBackbone("resnet18")
    decoder = SegmentationDecoder(backbone.channels, mdim=8).eval()
    settings = FRTMSettings(channels=8, num_aug=3, memory_size=8, init_schedule=(3, 5), update_schedule=(5,),
                            update_every=2, label_stride=2)
    tracker = FRTMTracker(backbone, decoder, settings).eval()
    bundle = tmp_path_factory.mktemp("bundles") / "vos"
    export_bundle(tracker, bundle, 64, 96)
    return {"bundle": bundle, "tracker": tracker}


@pytest.fixture(scope="session")
def davos_setup(tmp_path_factory) -> dict:
    """A DAVOS bundle of a small untrained DAVOS tracker (returned too), exported at 64 x 96."""
    import torch

    from export.davos_onnx import export_bundle
    from models.builders import davos_system

    system = davos_system(backbone="resnet18", weights=None, projection_channels=8, encoding_channels=4, mdim=8,
                          encoder_dims=(4, 8, 8), pass_labels=True,
                          tracker={"init_iters": 3, "update_iters": 2, "memory_size": 5})
    _randomize_batch_norm(system)
    with torch.no_grad():  # a larger lambda keeps the untrained filters' scores in a range where masks vary
        system.net.optimizer.reg.fill_(0.05)
    tracker = system.make_tracker()
    bundle = tmp_path_factory.mktemp("bundles") / "davos"
    export_bundle(tracker, bundle, 64, 96)
    return {"bundle": bundle, "tracker": tracker}
