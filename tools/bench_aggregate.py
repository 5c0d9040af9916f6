"""Benchmark: the end of a large export (COCO JSON, data.yaml, summary.json from meta/).

Renders a small city_park export (--source images, 4 formats), then widens it to N images by
copying its per-image metadata (index, name and split set as an N-image export would have
them) and times ``write_aggregates`` in a fresh process, with its peak RSS. The aggregates
hold one record at a time (dataset/aggregate.py), so memory should stay flat in N; time is
linear (the JSON text of every annotation).

    .venv/bin/python tools/bench_aggregate.py [--images 2000] [--source 20] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_CHILD = r"""
import json, resource, sys, time
from aerial_synth.dataset.aggregate import write_aggregates
from aerial_synth.dataset.export import ExportConfig
cfg = ExportConfig(**json.loads(sys.argv[1]))
t = time.perf_counter()
write_aggregates(cfg, sys.argv[2])
print(json.dumps({"seconds": round(time.perf_counter() - t, 2),
                  "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
"""


def _positive(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=_positive, default=2000, help="images of the widened export")
    ap.add_argument("--source", type=_positive, default=20, help="images actually rendered")
    ap.add_argument("--keep", type=Path, default=None, help="build here and keep it")
    a = ap.parse_args(argv)
    if a.source > a.images:
        ap.error(f"--source {a.source}: at most --images ({a.images})")

    from aerial_synth.dataset.export import ExportConfig, export_dataset
    from aerial_synth.dataset.layout import meta_path

    base = tempfile.TemporaryDirectory(prefix="aerial-synth-agg-")
    root = a.keep or Path(base.name)
    src_dir, wide_dir = root / "source", root / "wide"
    fields = dict(scene="city_park", formats="dota,eagle,yolo-obb,coco", seed=0)
    export_dataset(ExportConfig(images=a.source, **fields), src_dir, workers=2, progress=False)
    wide = ExportConfig(images=a.images, **fields)
    metas = [json.loads(meta_path(src_dir, i).read_text()) for i in range(a.source)]
    for i in range(a.images):
        d = dict(metas[i % a.source])
        d["image"] = dict(d["image"], index=i, name=f"{i:06d}", file_name=f"{i:06d}.png",
                          split="train" if i < wide.n_train else "val")
        p = meta_path(wide_dir, i)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(json.dumps(d))
    meta_mb = sum(f.stat().st_size for f in (wide_dir / "meta").iterdir()) / 1e6
    out = subprocess.run([sys.executable, "-c", _CHILD, json.dumps({"images": a.images, **fields}),
                          str(wide_dir)], capture_output=True, text=True, cwd=ROOT, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    coco_mb = sum(f.stat().st_size for f in (wide_dir / "coco" / "annotations").iterdir()) / 1e6
    print(f"{a.images} images ({meta_mb:.0f} MB of metadata): aggregates {res['seconds']} s, "
          f"peak RSS {res['peak_rss_mb']} MB; COCO JSON {coco_mb:.0f} MB")
    base.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
