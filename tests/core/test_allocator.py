"""core/allocator.py: freed memory stays in the process, counted by the kernel's minor page faults."""

import subprocess
import sys

import pytest

# A 40 MB block is above glibc's largest dynamic mmap threshold (32 MB), so by default every allocation of it maps
# fresh pages, which fault in when written (how many depends on the kernel's huge-page setting: about 570 here,
# 10000 with 4 KiB pages alone); kept memory is written without faults.
_SCRIPT = """
import resource
import numpy as np
from core.allocator import retain_freed_memory

def faults_per_block():
    np.ones(5_000_000).sum()  # the first block may fault either way
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(5):
        np.ones(5_000_000).sum()
    return (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 5

default = faults_per_block()
applied = retain_freed_memory()
print(default, applied, faults_per_block())
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_retained_memory_is_reused_without_page_faults():
    out = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True, check=True).stdout
    default, applied, retained = out.split()
    assert applied == "True"
    assert float(default) > 100
    assert float(retained) < 0.05 * float(default)
