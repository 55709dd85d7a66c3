"""``infer.py demo --quick``: every part runs, the report's images exist, are valid and not blank, the page is
well-formed, and the console carries no Lightning banner, tip or deprecation line."""

import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import pytest

from cli.demo import DEMOS

ROOT = Path(__file__).resolve().parents[2]
NOISE = re.compile(
    r"GPU available|TPU available|💡 Tip|Seed set to|Loading `train_dataloader`|litlogger|[Dd]eprecat|Warning:|it/s\]"
)


@pytest.mark.slow
def test_quick_demo_writes_a_valid_report_and_a_quiet_console(tmp_path) -> None:
    proc = subprocess.run([sys.executable, "infer.py", "demo", "--quick", "--out", str(tmp_path / "demo")], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    console = proc.stdout + proc.stderr
    assert not [line for line in console.splitlines() if NOISE.search(line)]
    for name in DEMOS:
        assert f"=== {name} " in proc.stdout and f"({name}: " in proc.stdout
    page = tmp_path / "demo" / "index.html"
    assert proc.stdout.strip().endswith(f"report: {page} (open it in a browser)")
    tree = ET.parse(page)  # well-formed
    ns = {"h": "http://www.w3.org/1999/xhtml"}
    images = [img.get("src") for img in tree.getroot().iterfind(".//h:img", ns)]
    sections = tree.getroot().findall(".//h:section", ns)
    assert len(sections) == len(DEMOS) and len(images) >= len(DEMOS)
    for src in images:
        path = tmp_path / "demo" / src
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", src
        image = cv2.imread(str(path))
        assert image is not None and image.shape[0] > 100 and image.std() > 10, src  # decodes, not blank
