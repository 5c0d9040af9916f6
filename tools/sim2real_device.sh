#!/usr/bin/env bash
# One arm of the issue-29 measurement (docs/gsd.md) on a GPU machine whose Python already
# has torch, torchvision, numpy, opencv-python-headless, pyyaml and matplotlib but not the
# rest of aerial-synth's dependencies: sim2real needs only shapely and Ultralytics besides,
# installed from local wheels (nothing is downloaded).
#
#   tools/sim2real_device.sh NAME DIR [MINUTES]
#
# NAME=DIR is the arm (an export with yolo-obb/), MINUTES its training time (3.5). Reads the
# real development set from $REAL (.s2r/real, DOTA layout, as docs/gsd.md describes) and the
# wheels from $WHEELS (.whl: shapely 2.2.0 for the Python there, ultralytics 8.4.190,
# ultralytics-thop 2.2.3). Writes log.txt and report.tgz (the whole sim2real report but
# last.pt) into $OUT (default /tmp/sim2real-device).
set -euo pipefail
name=${1:?usage: tools/sim2real_device.sh NAME DIR [MINUTES]}
dir=${2:?usage: tools/sim2real_device.sh NAME DIR [MINUTES]}
minutes=${3:-3.5}
device=${DEVICE:-0}
real=${REAL:-.s2r/real}
wheels=${WHEELS:-.whl}
out=${OUT:-/tmp/sim2real-device}
mkdir -p "$out"
if ! python3 -c 'import shapely, ultralytics' 2>/dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site "$wheels"/*.whl
    export PYTHONPATH=/tmp/site
fi
export PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$PWD PYTHONUNBUFFERED=1
{
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
    python3 -c 'import sys, torch, numpy, cv2, shapely, aerial_synth.sim2real.pipeline
print("python", sys.version.split()[0], "torch", torch.__version__, "cuda", torch.cuda.is_available(),
      "numpy", numpy.__version__, "cv2", cv2.__version__, "shapely", shapely.__version__)'
    report=/tmp/sim2real-$name
    rm -rf "$report"
    time python3 -m aerial_synth.cli sim2real --synthetic "$name=$dir" --real "$real" \
        --real-gsd 0.24 --ignore-border minsk_uav=40 --minutes "$minutes" --imgsz 640 \
        --batch 16 --workers 8 --device "$device" --seed 0 --real-scale arm,native --out "$report"
    tar czf "$out/report-$name.tgz" --exclude=last.pt -C /tmp "sim2real-$name"
} 2>&1 | tee "$out/log-$name.txt"
