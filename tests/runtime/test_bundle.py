"""Deployment bundles: the manifest a bundle is opened with, and each way a bundle can be wrong (another task, a
graph missing or changed, a manifest edited, graphs of another revision), named in one InputError."""

import json
import shutil

import pytest

from core.errors import InputError
from runtime.bundle import MANIFEST, TASK_REVISIONS, Bundle, file_sha256, model_hash

pytestmark = pytest.mark.slow  # uses an exported bundle


@pytest.fixture
def bundle(triangulation_bundle, tmp_path):
    """A copy of the triangulation bundle that a test may break."""
    return shutil.copytree(triangulation_bundle, tmp_path / "bundle")


def test_manifest_names_the_task_graphs_and_their_hashes(bundle) -> None:
    opened = Bundle(bundle, "triangulation")
    manifest = opened.manifest
    assert manifest["task"] == "triangulation" and manifest["opset"] == 20 and manifest["precision"] == "float32"
    assert set(manifest["graphs"]) == {"dogleg_start", "dogleg_start_shared", "dogleg_step"}
    for name, entry in manifest["graphs"].items():
        assert entry["sha256"] == file_sha256(bundle / f"{name}.onnx")
    assert manifest["model_hash"] == model_hash(manifest["graphs"])
    assert opened.section("input")["views"] == 3 and opened.section("thresholds")["iterations"] == 5
    assert opened.graph("dogleg_start").input_names == ["cameras", "observations"]
    assert opened.graph("dogleg_step").input_names == ["rows", "state", "active"]
    assert sorted(p.name for p in bundle.iterdir()) == ["bundle.json", "dogleg_start.onnx", "dogleg_start_shared.onnx",
                                                          "dogleg_step.onnx"]


def _edit_manifest(bundle, change) -> None:
    manifest = json.loads((bundle / MANIFEST).read_text())
    change(manifest)
    (bundle / MANIFEST).write_text(json.dumps(manifest))


def test_bad_bundles_are_named(bundle, tmp_path) -> None:
    with pytest.raises(InputError, match="is a 'triangulation' bundle, not a 'vos' bundle"):
        Bundle(bundle, "vos")
    with pytest.raises(InputError, match="no bundle.json"):
        Bundle(tmp_path, "triangulation")
    with pytest.raises(InputError, match="not a folder"):
        Bundle(tmp_path / "missing", "triangulation")
    graph = (bundle / "dogleg_step.onnx").read_bytes()
    (bundle / "dogleg_step.onnx").write_bytes(graph[:-1] + bytes([graph[-1] ^ 1]))
    with pytest.raises(InputError, match="dogleg_step.onnx does not match its hash"):
        Bundle(bundle, "triangulation")
    (bundle / "dogleg_step.onnx").unlink()
    with pytest.raises(InputError, match="is missing its graph dogleg_step.onnx"):
        Bundle(bundle, "triangulation")


def test_edited_manifests_are_refused(bundle) -> None:
    _edit_manifest(bundle, lambda m: m["graphs"].pop("dogleg_start_shared"))
    with pytest.raises(InputError, match="lists no graph dogleg_start_shared"):
        Bundle(bundle, "triangulation")
    (bundle / MANIFEST).write_text("{ not json")
    with pytest.raises(InputError, match="not valid JSON"):
        Bundle(bundle, "triangulation")


def test_a_changed_model_hash_is_refused(bundle) -> None:
    _edit_manifest(bundle, lambda m: m.update(model_hash="0" * 64))
    with pytest.raises(InputError, match="model hash"):
        Bundle(bundle, "triangulation")


def test_graphs_of_another_revision_are_refused(bundle, tracking_bundle, tmp_path) -> None:
    assert Bundle(bundle, "triangulation").manifest["revision"] == TASK_REVISIONS["triangulation"] == 1
    _edit_manifest(bundle, lambda m: m.pop("revision"))
    assert Bundle(bundle, "triangulation").manifest["task"] == "triangulation"  # no revision: revision 1
    _edit_manifest(bundle, lambda m: m.update(revision=2))
    with pytest.raises(InputError, match="revision 2 triangulation graphs; this runtime runs revision 1: export the "
                                         "bundle again with python -m export.triangulation"):
        Bundle(bundle, "triangulation")
    old_tracking = shutil.copytree(tracking_bundle, tmp_path / "tracking")
    _edit_manifest(old_tracking, lambda m: m.pop("revision"))  # written before the snr graph masked points itself
    with pytest.raises(InputError, match="revision 1 tracking graphs; this runtime runs revision 6"):
        Bundle(old_tracking, "tracking")
    _edit_manifest(old_tracking, lambda m: m.update(revision=2))  # written before the first-step retry's graphs
    with pytest.raises(InputError, match="revision 2 tracking graphs; this runtime runs revision 6"):
        Bundle(old_tracking, "tracking")
    _edit_manifest(old_tracking, lambda m: m.update(revision=3))  # written before the turn graph
    with pytest.raises(InputError, match="revision 3 tracking graphs; this runtime runs revision 6"):
        Bundle(old_tracking, "tracking")
    _edit_manifest(old_tracking, lambda m: m.update(revision=4))  # written before the turn graph counted the points
    with pytest.raises(InputError, match="revision 4 tracking graphs; this runtime runs revision 6"):
        Bundle(old_tracking, "tracking")
    _edit_manifest(old_tracking, lambda m: m.update(revision=5))  # written before the fifth pyramid level
    with pytest.raises(InputError, match="revision 5 tracking graphs; this runtime runs revision 6"):
        Bundle(old_tracking, "tracking")
