"""Benchmark: the end of a large export (COCO JSON, data.yaml, summary.json from meta/).

Renders a small city_park export (--source images, 4 formats), then widens it to N images by
copying its per-image metadata (index, name and split set as an N-image export would have
them) and times ``write_aggregates`` in a fresh process, with its peak RSS, twice: with 1
worker (everything in that process) and with the default pool (every allowed core; each
process reads and formats chunks of records, see ``MetaRecords.map``). For the pool, the
export's fork server is started and waited for first, as an export of that size starts it
at its beginning; its start is reported apart. Records are held a few at a time
(dataset/aggregate.py), so memory should stay flat in N; time is linear (the JSON text of
every annotation). The peak RSS is the aggregating process's own (VmHWM; a pool process has
its own).

    .venv/bin/python tools/bench_aggregate.py [--images 2000] [--source 20] [--keep DIR]

With --keep DIR, a DIR/source rendered before (same --source) is used again.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_CHILD = r"""
import json, resource, sys, time
from aerial_synth.dataset.aggregate import MetaRecords, write_aggregates
from aerial_synth.dataset.export import ExportConfig, pool_context, start_pool_server

if __name__ == "__main__":
    cfg = ExportConfig(**json.loads(sys.argv[1]))
    workers = None if sys.argv[3] == "default" else int(sys.argv[3])
    pool = MetaRecords(cfg, sys.argv[2], workers=workers).pool_size(cfg.images)
    server = 0.0
    if pool > 1:  # as an export starts it at its beginning: ready at its end
        t = time.perf_counter()
        start_pool_server()
        with pool_context().Pool(1) as p:  # returns once the server has made its imports
            p.map(abs, [1])
        server = time.perf_counter() - t
    t = time.perf_counter()
    write_aggregates(cfg, sys.argv[2], workers=workers)
    try:  # this process's own peak (ru_maxrss also counts what the parent had when it forked)
        hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM:")][0].split()[1]
    except (OSError, IndexError):
        hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"seconds": round(time.perf_counter() - t, 2), "processes": pool,
                      "server_seconds": round(server, 2), "peak_rss_mb": round(int(hwm) / 1024, 1)}))
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
    have = sorted(p.name for p in (src_dir / "meta").glob("*.json")) if a.keep else []
    if have != [meta_path(src_dir, i).name for i in range(a.source)] or not (src_dir / "summary.json").is_file():
        export_dataset(ExportConfig(images=a.source, **fields), src_dir, workers=2, force=True, progress=False)
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
    child = root / "bench_aggregate_child.py"  # a file: the pool's processes import it (guarded)
    child.write_text(_CHILD)
    runs, outputs = [], []
    for workers in ("1", "default"):
        out = subprocess.run([sys.executable, str(child), json.dumps({"images": a.images, **fields}),
                              str(wide_dir), workers], capture_output=True, text=True, cwd=ROOT, check=True)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        outputs.append({p: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(wide_dir.rglob("*"))
                        if p.is_file() and "meta" not in p.relative_to(wide_dir).parts})
    coco_mb = sum(f.stat().st_size for f in (wide_dir / "coco" / "annotations").iterdir()) / 1e6
    print(f"{a.images} images ({meta_mb:.0f} MB of metadata, COCO JSON {coco_mb:.0f} MB out):")
    for name, res in zip(("1 worker", "default"), runs):
        server = f" (+ {res['server_seconds']} s to start the fork server)" if res["server_seconds"] else ""
        print(f"  {name:8s} {res['processes']} process(es): aggregates {res['seconds']} s{server}, "
              f"peak RSS {res['peak_rss_mb']} MB")
    print(f"  same bytes: {outputs[0] == outputs[1]}")
    child.unlink()
    base.cleanup()
    return 0 if outputs[0] == outputs[1] else 1


if __name__ == "__main__":
    sys.exit(main())
