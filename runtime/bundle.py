"""Deployment bundles: a folder holding one task's ONNX graphs and ``bundle.json``, the manifest the runtime
checks before it runs anything.

    bundle.json   {"format": "dcfvision-bundle", "version": 1, "task": "vos", "revision": 1, "opset": 20,
                   "precision": "float32", "graphs": {"frame": {"file": "frame.onnx", "sha256": "..."}, ...},
                   "model_hash": "...", "input": {...}, "normalisation": {...}, "thresholds": {...}, "settings": {...}}

``input`` states what the graphs accept (image layout, sizes), ``normalisation`` how pixels are scaled before the
graphs, ``thresholds`` the decision values built into them and ``settings`` what the host loop needs. The model
hash is the SHA-256 of the graphs' hashes: it names the model as a whole. ``revision`` counts changes of one task's
graph interface (``TASK_REVISIONS``; a manifest without it is revision 1), so a runtime refuses graphs of another
revision with the command that writes them again. Opening a bundle checks the format, the task and its revision,
that every graph of the task is listed and present, and each graph's SHA-256; any mismatch is an
``InputError`` naming the bundle.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path
from typing import Any

from core.errors import InputError
from core.files import write_text
from runtime.session import PROVIDERS, Graph

MANIFEST = "bundle.json"
FORMAT = "dcfvision-bundle"
VERSION = 1
#: The graphs of each task's bundle, ``<name>.onnx``.
TASK_GRAPHS = {
    "triangulation": ("dogleg_start", "dogleg_start_shared", "dogleg_step"),
    "tracking": ("init", "step", "profile", "relative_blur", "streak", "snr", "init_low_snr", "step_low_snr",
                 "first_step_noise", "turn", "init_large", "step_large", "init_low_snr_large", "step_low_snr_large"),
    "horizon": ("finder", "level", "segmenter", "matcher"),
    "vos": ("frame", "features", "init", "insert", "update"),
    "davos": ("features", "frame", "encode", "insert", "fit_init", "fit_update"),
}
#: The revision of each task's graph interface, raised when the graphs' inputs, outputs or contract change (tracking
#: 2: the ``snr`` graph leaves out the points outside the frame itself, so the runtime no longer filters them; 3: the
#: ``first_step_noise`` graph and the ``noise_floor`` input of ``step_low_snr``; 4: the ``turn`` graph and the
#: ``turn_match`` threshold; 5: the ``turn`` graph reads 0 where fewer than 10 points are tracked, which the runtime
#: no longer counts itself; 6: the ``*_large`` graphs of five pyramid levels for frames large enough for the fifth,
#: and the ``large_levels`` and ``large_min_side`` entries of the manifest's ``input``).
TASK_REVISIONS = {"triangulation": 1, "tracking": 6, "horizon": 1, "vos": 1, "davos": 1}
#: The command that writes each task's bundle (named in error messages).
EXPORT_COMMANDS = {"triangulation": "export.triangulation", "tracking": "export.tracking_onnx",
                   "horizon": "export.horizon_onnx", "vos": "export.vos_onnx", "davos": "export.davos_onnx"}


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def model_hash(graphs: dict[str, dict]) -> str:
    """SHA-256 of the graphs' hashes in name order: one identifier for the model of a bundle."""
    return hashlib.sha256("".join(graphs[name]["sha256"] for name in sorted(graphs)).encode()).hexdigest()


def write_manifest(folder: str | Path, task: str, opset: int, precision: str = "float32", **sections: Any) -> Path:
    """Write ``bundle.json`` for the graphs ``<name>.onnx`` of ``task`` in ``folder`` (hashes computed here) with
    the manifest ``sections`` (``input``, ``normalisation``, ``thresholds``, ``settings``, ...); returns its path."""
    if task not in TASK_GRAPHS:
        raise InputError(f"unknown bundle task {task!r}; known: {', '.join(TASK_GRAPHS)}")
    folder = Path(folder)
    graphs = {name: {"file": f"{name}.onnx", "sha256": file_sha256(folder / f"{name}.onnx")}
              for name in TASK_GRAPHS[task]}
    manifest = {"format": FORMAT, "version": VERSION, "task": task, "revision": TASK_REVISIONS[task], "opset": opset,
                "precision": precision, "graphs": graphs, "model_hash": model_hash(graphs), **sections}
    return write_text(folder / MANIFEST, json.dumps(manifest, indent=1))


def bundle_task(path: str | Path) -> str:
    """The task a bundle folder's manifest names (not yet checked: ``Bundle`` does that); ``InputError`` when the
    folder holds no readable manifest."""
    file = Path(path) / MANIFEST
    try:
        task = json.loads(file.read_text()).get("task")
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, AttributeError) as err:
        raise InputError(f"{path} is not a deployment bundle: {file} cannot be read ({err})") from err
    if task not in TASK_GRAPHS:
        raise InputError(f"bundle {path} names an unknown task {task!r}; known: {', '.join(TASK_GRAPHS)}")
    return task


class Bundle:
    """A checked deployment bundle of ``task``.

    Args:
        path: the bundle folder; task: a key of ``TASK_GRAPHS``; threads, provider: how its graphs run
            (``runtime.session.Graph``).

    Attributes:
        manifest: the parsed ``bundle.json``.
    """

    def __init__(self, path: str | Path, task: str, threads: int | None = None, provider: str = "cpu") -> None:
        self.path, self.task, self.threads, self.provider = Path(path), task, threads, provider
        self.manifest = self._read()
        self._check_graphs()

    def _read(self) -> dict:
        export = f"python -m {EXPORT_COMMANDS[self.task]}"
        if not self.path.is_dir():
            raise InputError(f"bundle {self.path} is not a folder (write a {self.task} bundle with {export})")
        file = self.path / MANIFEST
        if not file.is_file():
            raise InputError(f"{self.path} is not a deployment bundle: it has no {MANIFEST} (write one with {export})")
        try:
            manifest = json.loads(file.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise InputError(f"bundle manifest {file} is not valid JSON: {err}") from err
        if not isinstance(manifest, dict) or manifest.get("format") != FORMAT or manifest.get("version") != VERSION:
            raise InputError(f"{file} is not a version {VERSION} {FORMAT} manifest")
        if manifest.get("task") != self.task:
            raise InputError(f"bundle {self.path} is a {manifest.get('task')!r} bundle, not a {self.task!r} bundle")
        revision = manifest.get("revision", 1)
        if revision != TASK_REVISIONS[self.task]:
            raise InputError(f"bundle {self.path} holds revision {revision!r} {self.task} graphs; this runtime runs "
                             f"revision {TASK_REVISIONS[self.task]}: export the bundle again with {export}")
        return manifest

    def _check_graphs(self) -> None:
        graphs = self.manifest.get("graphs")
        listed = graphs if isinstance(graphs, dict) else {}
        missing = [g for g in TASK_GRAPHS[self.task] if g not in listed]
        if missing:
            raise InputError(f"bundle {self.path}: {MANIFEST} lists no graph {', '.join(missing)}")
        for name in TASK_GRAPHS[self.task]:
            file = self.path / str(listed[name].get("file", ""))
            if not file.is_file():
                raise InputError(f"bundle {self.path} is missing its graph {file.name}")
            if file_sha256(file) != listed[name].get("sha256"):
                raise InputError(f"bundle {self.path}: {file.name} does not match its hash in {MANIFEST} (the graph "
                                 "was changed or is corrupt; export the bundle again)")
        if model_hash(listed) != self.manifest.get("model_hash"):
            raise InputError(f"bundle {self.path}: the model hash in {MANIFEST} does not match its graphs' hashes")

    def graph(self, name: str) -> Graph:
        """Session of graph ``name`` of the bundle."""
        return Graph(self.path / self.manifest["graphs"][name]["file"], self.threads, self.provider)

    def section(self, name: str) -> dict:
        """A manifest section (``input``, ``normalisation``, ``thresholds``, ``settings``); ``{}`` if absent."""
        value = self.manifest.get(name, {})
        if not isinstance(value, dict):
            raise InputError(f"bundle {self.path}: {MANIFEST} entry {name!r} is not a mapping")
        return value

    def __repr__(self) -> str:
        return f"Bundle({str(self.path)!r}, task={self.task!r}, model_hash={self.manifest['model_hash'][:12]!r})"


def add_runtime_arguments(parser: argparse.ArgumentParser) -> None:
    """``--bundle``, ``--threads`` and ``--provider``, shared by every runtime command."""
    parser.add_argument("--bundle", type=Path, required=True, metavar="DIR", help="deployment bundle folder")
    parser.add_argument("--threads", type=int, default=None,
                        help="onnxruntime intra-op threads (default: onnxruntime's; 1 on a shared CPU)")
    parser.add_argument("--provider", choices=tuple(PROVIDERS), default="cpu", help="execution provider")
