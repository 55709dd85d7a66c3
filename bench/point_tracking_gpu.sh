#!/usr/bin/env bash
# The point tracker's GPU checks, as one run on a machine with a CUDA device (not yet run on a GPU: none was lent;
# on a CPU its benchmarks and the tracker's tests, the CUDA test skipped, also run under torch 2.11, the GPU
# machine's; the project's ONNX export stops there, and this script exports nothing):
#   1. the tracker on CUDA against the CPU (tests/models/tracking: test_tracks_on_cuda_match_the_cpu);
#   2. ccot on the GPU beside KLT on one CPU thread at 2000 points, accuracy included (the synthetic sequence);
#   3. point-frames per second at 1e3, 1e4 and 1e5 points (a grid over the synthetic frames, every pixel, in a
#      seeded order), with the per-frame and per-point costs of bench/point_tracking_scaling.py.
# Every run is timed by the wall clock after a synchronisation. Writes device.txt, tests.txt, points_2000.json,
# scaling.json and scaling.png to OUT_DIR.
#
#   bench/point_tracking_gpu.sh OUT_DIR
#
# PYTHON (default python3) is the interpreter; DEVICE (default cuda) and POINTS (default "1000 10000 100000")
# exist so that the script can be tried on a CPU with small counts: DEVICE=cpu POINTS="100 1000".
set -euo pipefail
mkdir -p "${1:?usage: bench/point_tracking_gpu.sh OUT_DIR}"
out=$(cd "$1" && pwd)  # absolute: the runs start from the repository root
python=${PYTHON:-python3}
device=${DEVICE:-cuda}
read -r -a points <<<"${POINTS:-1000 10000 100000}"
cd "$(dirname "$0")/.."

"$python" - "$device" <<'EOF' | tee "$out/device.txt"
import sys

import torch

from core.checks import check_device

device = check_device(sys.argv[1])
name = torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu"
print(f"torch {torch.__version__}, device {device}: {name}")
EOF
tests=0
if [ "$device" != cpu ]; then  # the benchmarks run whatever the tests say; the script's status is theirs
    "$python" -m pytest -q -p no:cacheprovider tests/models/tracking/test_point_tracker.py -k cuda 2>&1 |
        tee "$out/tests.txt" || tests=$?
fi
"$python" -m bench.point_tracking --synthetic --points 2000 --methods ccot klt --device "$device" --repeats 3 \
    --threads 1 --json >"$out/points_2000.json"
"$python" -m bench.point_tracking_scaling --synthetic --length 8 --grid 1 --points "${points[@]}" \
    --device "$device" --repeats 3 --threads 1 --json --plot "$out/scaling.png" >"$out/scaling.json"
ls "$out"
exit "$tests"
