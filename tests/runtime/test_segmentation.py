"""The runtime's choice of VOS tracker by a bundle's task: FRTM for ``vos``, DAVOS for ``davos``, an error naming
the bundle for any other task."""

import json

import pytest

from core.errors import InputError
from runtime.davos import OnnxDAVOSTracker
from runtime.segmentation import segmentation_tracker, segmentation_tracker_type
from runtime.vos import OnnxFRTMTracker


@pytest.mark.parametrize("task", ["tracking", "triangulation", "horizon"])
def test_a_bundle_of_another_task_is_refused_by_name(task: str, tmp_path) -> None:
    (tmp_path / "bundle.json").write_text(json.dumps({"format": "dcfvision-bundle", "task": task}))
    with pytest.raises(InputError, match=rf"{tmp_path}.*'{task}' bundle.*'vos' or 'davos'"):
        segmentation_tracker_type(tmp_path)


def test_a_folder_without_manifest_is_refused(tmp_path) -> None:
    with pytest.raises(InputError, match="not a deployment bundle"):
        segmentation_tracker(tmp_path)


@pytest.mark.slow  # uses exported bundles
def test_each_segmentation_bundle_gets_its_tracker(vos_setup, davos_setup) -> None:
    frtm, davos = segmentation_tracker(vos_setup["bundle"], threads=1), segmentation_tracker(davos_setup["bundle"])
    assert type(frtm) is OnnxFRTMTracker and type(davos) is OnnxDAVOSTracker
    assert frtm.bundle.path == vos_setup["bundle"] and davos.bundle.path == davos_setup["bundle"]
    assert frtm.bundle.threads == 1 and davos.bundle.threads is None
