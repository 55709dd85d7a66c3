"""Writing output files so that a killed job never leaves a file that looks whole: everything is written to a
temporary name beside the target and renamed over it only when complete (``os.replace`` is atomic on one file
system). ``write_npz`` is also byte-deterministic (fixed zip timestamps), so a resumed job can be compared with
an uninterrupted one byte for byte."""

from __future__ import annotations

import io
import os
import shutil
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from core.errors import InputError

#: Timestamp of every member of the zip archives written here (the zip format's epoch).
ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


def partial_name(path: Path) -> Path:
    """The temporary name ``path`` is written under: ``.STEM.PID.partial.SUFFIX`` beside it (hidden, so never taken
    for the file; the process id, so processes writing the same file do not collide; the suffix kept, so writers
    that choose a format by suffix still work)."""
    return path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")


def remove_partials(folder: str | Path) -> None:
    """Remove the temporary files (``partial_name``) that killed writers left in ``folder``, before a resumed job
    writes there again (a kill between writing and renaming leaves one behind)."""
    folder = Path(folder)
    if folder.is_dir():
        for stale in folder.glob(".*.partial*"):
            if stale.is_file():
                stale.unlink(missing_ok=True)


def staging_folder(folder: Path) -> Path:
    """A fresh, empty ``.NAME.PID.partial`` folder beside ``folder`` to write into before moving the files into
    place. Staging folders of earlier writers of ``folder`` whose process is gone (a killed run) are removed;
    those of running processes are kept."""
    for stale in folder.parent.glob(f".{folder.name}.*.partial"):
        pid = stale.name[len(folder.name) + 2 : -len(".partial")]
        if stale.is_dir() and pid.isdigit() and not _process_alive(int(pid)):
            shutil.rmtree(stale, ignore_errors=True)
    staging = folder.with_name(f".{folder.name}.{os.getpid()}.partial")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    return staging


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def writable_folder(folder: str | Path) -> Path:
    """``folder``, created if missing; an ``InputError`` naming it when it cannot be created or written."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"cannot create the output folder {folder}: {err.strerror or err}") from err
    if not os.access(folder, os.W_OK):
        raise InputError(f"the output folder {folder} is not writable")
    return folder


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write; on leaving the block it is renamed to ``path`` (removed on an error).

    An output folder that cannot be created or written is an ``InputError`` naming it.
    """
    path = Path(path)
    writable_folder(path.parent)
    tmp = partial_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    return write_bytes(path, text.encode())


def npz_bytes(arrays: dict[str, np.ndarray], compress: bool = True) -> bytes:
    """A ``.npz`` archive of ``arrays`` (readable by ``np.load``) whose bytes depend only on the arrays."""
    buffer = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(buffer, "w", compression=method) as archive:
        for name, value in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=ZIP_EPOCH)
            info.compress_type = method
            archive.writestr(info, member.getvalue())
    return buffer.getvalue()


def write_npz(path: str | Path, compress: bool = True, **arrays: np.ndarray) -> Path:
    """Write ``arrays`` as a ``.npz`` archive to ``path``, atomically and byte-deterministically."""
    return write_bytes(path, npz_bytes(arrays, compress))
