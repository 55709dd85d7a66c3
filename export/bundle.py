"""Writing deployment bundles (``runtime.bundle``): every graph and the manifest go to a hidden staging folder
beside the target, which replaces the target only when all of them were written and checked, so a failed export
leaves neither a partial bundle nor a mix of two."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from core.errors import InputError
from core.files import writable_folder
from runtime.bundle import MANIFEST


@contextmanager
def staged_bundle(out: str | Path) -> Iterator[Path]:
    """Yield an empty staging folder; on leaving the block it becomes ``out`` (an existing bundle there is
    replaced). ``out`` must be new, empty or a bundle: any other folder is an ``InputError``."""
    final = Path(out)
    try:
        writable_folder(final.parent)
    except InputError as err:
        raise InputError(f"cannot write the bundle {final}: {err}") from err
    if final.exists() and not (final.is_dir() and (not any(final.iterdir()) or (final / MANIFEST).is_file())):
        raise InputError(f"--out {final} exists and is not a bundle folder; give a new or empty folder")
    staging = final.with_name(f".{final.name}.{os.getpid()}.partial")
    old = final.with_name(f".{final.name}.{os.getpid()}.old")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        yield staging
        if final.exists():
            os.replace(final, old)
        os.replace(staging, final)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
