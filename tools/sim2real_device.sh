#!/usr/bin/env bash
# A whole sim2real experiment in one call on a GPU machine (docs/sim2real.md):
#
#   tools/sim2real_device.sh PLAN
#
# 1. the wheels in $WHEELS (tools/device_wheels.py: shapely, trimesh, a slim open3d-cpu, isal,
#    pycocotools, Ultralytics) are installed into /tmp/site when aerial-synth's export or
#    Ultralytics cannot be imported (nothing is downloaded);
# 2. `aerial-synth sim2real --plan PLAN` exports the arms here on all CPU cores (no image
#    travels with the call), trains the runs in parallel on the GPU (--parallel $PARALLEL,
#    auto by default), scores them and writes the report into $REPORT;
# 3. $OUT receives at most 8 files of at most 16 MiB: log.txt, summary.txt, report.tgz
#    (report.json, summary.txt, pr*.png, contact_*.png, plan.json, each run's result.json,
#    log.txt and results.csv) and weights-N.tar (the weights of every arm's first seed, as
#    runs/<arm>/seed<S>/weights.pt, packed into tars of at most 15 MiB).
#
# Variables: DEVICE (0; cpu for a dry run), PARALLEL (auto), EXPORT_WORKERS (all cores),
# WHEELS (.whl), REPORT (/tmp/sim2real-plan), OUT (/tmp/sim2real-device).
set -euo pipefail
plan=${1:?usage: tools/sim2real_device.sh PLAN}
device=${DEVICE:-0}
parallel=${PARALLEL:-auto}
workers=${EXPORT_WORKERS:-$(nproc)}
wheels=${WHEELS:-.whl}
report=${REPORT:-/tmp/sim2real-plan}
out=${OUT:-/tmp/sim2real-device}
py=${PYTHON:-python3}
mkdir -p "$out"
t0=$(date +%s)
if ! "$py" -c 'import shapely, trimesh, open3d, ultralytics' 2>/dev/null; then
    "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site "$wheels"/*.whl
    export PYTHONPATH=/tmp/site
fi
export PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$PWD PYTHONUNBUFFERED=1
{
    echo "setup: $(( $(date +%s) - t0 )) s"
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null || echo "no nvidia-smi"
    "$py" -c 'import sys, torch, numpy, cv2, shapely, open3d, ultralytics
print("python", sys.version.split()[0], "torch", torch.__version__, "cuda", torch.cuda.is_available(),
      "numpy", numpy.__version__, "cv2", cv2.__version__, "shapely", shapely.__version__,
      "open3d", open3d.__version__, "ultralytics", ultralytics.__version__)'
    t1=$(date +%s)
    "$py" -m aerial_synth.cli sim2real --plan "$plan" --out "$report" --parallel "$parallel" \
        --device "$device" --export-workers "$workers"
    echo "sim2real: $(( $(date +%s) - t1 )) s; whole call: $(( $(date +%s) - t0 )) s"
} 2>&1 | tee "$out/log.txt"
cp "$report/summary.txt" "$out/summary.txt"
( cd "$report" && tar czf "$out/report.tgz" report.json summary.txt plan.json ./*.png \
    runs/*/seed*/result.json runs/*/seed*/log.txt runs/*/seed*/train/results.csv 2>/dev/null || \
  tar czf "$out/report.tgz" report.json summary.txt plan.json ./*.png runs/*/seed*/result.json )
# the first seed's weights of every arm, in tars of at most 15 MiB (at most 5 tars: 8 files in all)
"$py" - "$report" "$out" <<'EOF'
import json, sys, tarfile
from pathlib import Path
report, out = Path(sys.argv[1]), Path(sys.argv[2])
rep = json.loads((report / "report.json").read_text())
files = [report / a["runs"][0]["weights"] for a in rep["arms"]]
limit, packs, cur, size = 15 * 2**20, [], [], 0
for f in files:
    n = f.stat().st_size
    if cur and size + n > limit:
        packs.append(cur)
        cur, size = [], 0
    cur.append(f)
    size += n
if cur:
    packs.append(cur)
if len(packs) > 5:
    sys.exit(f"{len(files)} weights files need {len(packs)} tars: more than 8 files would come back")
for i, pack in enumerate(packs, 1):
    with tarfile.open(out / f"weights-{i}.tar", "w") as t:
        for f in pack:
            t.add(f, arcname=str(f.relative_to(report)))
print(f"weights: {len(files)} files in {len(packs)} tar(s)")
EOF
ls -la "$out"
