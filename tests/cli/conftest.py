"""Helpers for the command tests: run ``infer.py`` in a subprocess, kill it part-way, and compare output trees."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def run_infer(argv: list[str]) -> tuple[int, float]:
    """Run ``infer.py argv`` to the end in a subprocess; (exit code, seconds)."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, str(ROOT / "infer.py"), *argv], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.returncode, time.perf_counter() - start


def file_count(root: Path) -> int:
    return sum(1 for p in root.rglob("*") if p.is_file()) if root.exists() else 0


def run_killed(argv: list[str], out: Path, extra_s: float) -> bool:
    """Start ``infer.py argv``, wait until it has written a new file under ``out`` (it is part-way), wait
    ``extra_s`` more seconds and SIGKILL it; True when it was still running then."""
    before = file_count(out)
    proc = subprocess.Popen([sys.executable, str(ROOT / "infer.py"), *argv], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    while proc.poll() is None and file_count(out) <= before:
        time.sleep(0.02)
    time.sleep(extra_s)
    if proc.poll() is not None:
        return False
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    return True


def kill_and_resume(argv: list[str], out: Path, kills: int, seed: int, max_extra_s: float = 1.0) -> int:
    """Run ``infer.py argv`` (writing under ``out``) ``kills`` times, each killed at a random point after it
    made progress, then once to the end; returns how many kills hit a running job."""
    rng = np.random.default_rng(seed)
    hit = sum(run_killed(argv, out, float(rng.uniform(0, max_extra_s))) for _ in range(kills))
    run_infer(argv)
    return hit


def tree_bytes(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> content)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}
