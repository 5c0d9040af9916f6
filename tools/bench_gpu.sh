#!/usr/bin/env bash
# The warp backend's GPU figures in one command (<= 10 minutes on a GPU machine, start-up
# included): images/s at 640 x 640 for buffers only, the fast and the full preset; export
# with PNG and JPEG encoding; the encoders on 1..8 threads; vehicle mesh refit vs rebuild;
# GPU utilisation sampled by nvidia-smi throughout; the stream feeding an Ultralytics
# training when this checkout has one (guarded: skipped, saying so, when it does not).
#
#   tools/bench_gpu.sh              # on the GPU machine: --device cuda
#   DEVICE=cpu FRAMES=3 EXPORT=3 tools/bench_gpu.sh    # the dry run on a CPU
#
# Uses .venv when it exists and imports warp (make install-test builds it from the test
# lock, warp-lang included); otherwise builds it first, which needs the package registry
# (or a pip mirror). Results: $OUT (default out/bench_gpu/), one JSON
# per part plus nvidia-smi.csv and summary.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
DEVICE=${DEVICE:-cuda}
SIZE=${SIZE:-640}
FRAMES=${FRAMES:-300}
EXPORT=${EXPORT:-300}
EXPORT_WORKERS=${EXPORT_WORKERS:-1,8}  # one export per count: 1 process, then 8 sharing the GPU
RAYCAST=${RAYCAST:---raycast}          # the CPU backend beside it ("" to skip)
OUT=${OUT:-out/bench_gpu}
BUDGET_S=${BUDGET_S:-540}  # the whole script stops here whatever is left (10 min limit)
PY=.venv/bin/python
mkdir -p "$OUT"
start=$(date +%s)
left() { echo $(( BUDGET_S - ($(date +%s) - start) )); }

[ -x "$PY" ] && "$PY" -c 'import warp' 2>/dev/null || make install-test
"$PY" -c 'import warp, aerial_synth; print("warp", warp.__version__, "aerial-synth", aerial_synth.__version__)' \
  | tee "$OUT/versions.txt"

SMI=""
if command -v nvidia-smi >/dev/null 2>&1; then
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv | tee -a "$OUT/versions.txt"
  nvidia-smi --query-gpu=timestamp,utilization.gpu,memory.used --format=csv -lms 500 \
    > "$OUT/nvidia-smi.csv" &
  SMI=$!
  trap '[ -n "$SMI" ] && kill "$SMI" 2>/dev/null || true' EXIT
else
  echo "no nvidia-smi: GPU utilisation not sampled" | tee -a "$OUT/versions.txt"
fi

# 1. buffers only, fast, full; refit vs rebuild; encoders; export with encoding
timeout "$(left)" "$PY" tools/bench_warp.py --device "$DEVICE" --size "$SIZE" \
  --frames "$FRAMES" --export "$EXPORT" --export-workers "$EXPORT_WORKERS" $RAYCAST \
  --encode 200 --json "$OUT/warp.json" \
  > "$OUT/warp.log" 2>&1 || echo "bench_warp.py stopped (status $?): see $OUT/warp.log"

# 2. the stream feeding an Ultralytics training, GPU utilisation sampled above: run by the
#    stream's own benchmark, tools/bench_stream.py (the stream issue's; it takes --backend,
#    --device, --size and --seconds), where this checkout has it and Ultralytics is installed
if [ -f tools/bench_stream.py ] && "$PY" -c 'import ultralytics' 2>/dev/null \
    && [ "$(left)" -gt 90 ]; then
  timeout "$(( $(left) - 15 ))" "$PY" tools/bench_stream.py --backend warp --device "$DEVICE" \
    --size "$SIZE" --seconds "$(( $(left) - 60 ))" > "$OUT/stream.log" 2>&1 \
    || echo "stream benchmark stopped (status $?): see $OUT/stream.log"
else
  echo "stream: skipped (no tools/bench_stream.py with Ultralytics in this checkout, or no time left)" \
    | tee "$OUT/stream.log"
fi

[ -n "$SMI" ] && kill "$SMI" 2>/dev/null || true
{
  cat "$OUT/versions.txt"
  "$PY" - "$OUT" <<'EOF'
import csv, json, sys
from pathlib import Path
out = Path(sys.argv[1])
try:
    r = json.loads((out / "warp.json").read_text())
except (OSError, ValueError):
    print("no warp.json: see warp.log"); sys.exit(0)
w = r["warp"]
print(f"device {r['device']} ({r['device_name']}), {r['size_px']} px, warp {r['warp_version']}")
for name in ("warp", "raycast"):
    for k in ("buffers", "fast", "full"):
        if k in r.get(name, {}):
            e = r[name][k]
            print(f"  {name:7s} {k:8s} {e['images_per_s']:9.1f} images/s ({e['images']} frames)")
for key, e in r.get("export", {}).items():
    print(f"  export {key}: {e['images_per_s']:.1f} images/s ({e['images']} images, {e['seconds']} s)")
print("  encoders (images/s):", r.get("encode", {}).get("images_per_s"))
print("  vehicle mesh:", r.get("vehicle_mesh"))
p = out / "nvidia-smi.csv"
if p.exists():
    rows = list(csv.reader(p.open()))[1:]
    u = [float(x[1].strip().split()[0]) for x in rows if len(x) > 1 and x[1].strip()[:1].isdigit()]
    if u:
        print(f"  GPU utilisation: mean {sum(u) / len(u):.0f} %, max {max(u):.0f} % ({len(u)} samples)")
EOF
  cat "$OUT/stream.log" | tail -n 3
  echo "total $(( $(date +%s) - start )) s"
} | tee "$OUT/summary.txt"
