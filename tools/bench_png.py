"""Benchmark: PNG encoding of rendered frames, this package's encoder against OpenCV's.

Renders ``--frames`` city_park jam frames (default 6; or reads the PNGs of an export with
``--from DIR``), then encodes each with :func:`aerial_synth.png.encode_png` (Average filter +
ISA-L level ``png.LEVEL``) and with OpenCV at the fallback's settings (zlib 1, Average,
Huffman-only) and at its defaults, rounds interleaved, on one core. Prints the median ms
and the mean MB of each, and checks that every file decodes to the frame's pixels.

    .venv/bin/python tools/bench_png.py [--frames 6] [--rounds 5] [--from DIR]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aerial_synth import png  # noqa: E402


def _frames_from(folder: Path, n: int) -> list[np.ndarray]:
    import cv2

    files = sorted(folder.rglob("*.png"))[:n]
    if not files:
        raise SystemExit(f"bench_png: --from {folder}: no .png files found")
    return [cv2.imread(str(p), cv2.IMREAD_COLOR)[..., ::-1].copy() for p in files]


def _render(n: int) -> list[np.ndarray]:
    import tempfile

    from aerial_synth.dataset.config import ExportConfig
    from aerial_synth.dataset.worker import ImageWorker

    cfg = ExportConfig(scene="city_park", scenario="jam", images=n, formats=("dota",), seed=0)
    w = ImageWorker.for_config(cfg, Path(tempfile.mkdtemp()), nthreads=1)
    return [w.record(i)[1] for i in range(n)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--from", dest="src", type=Path, default=None,
                    help="encode the PNGs of this folder (e.g. an export) instead of rendering")
    a = ap.parse_args(argv)
    if a.frames < 1 or a.rounds < 1:
        ap.error("--frames and --rounds: expected positive integers")
    import cv2

    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core, as a worker has
    except (AttributeError, OSError):
        pass
    cv2.setNumThreads(1)
    frames = _frames_from(a.src, a.frames) if a.src else _render(a.frames)
    fast = list(png.opencv_png_params())
    coders = {
        f"aerial_synth.png ({png.backend()}, level {png.LEVEL})": png.encode_png,
        "OpenCV zlib 1, Average, Huffman-only": lambda f: cv2.imencode(".png", f[..., ::-1].copy(), fast)[1].tobytes(),
        "OpenCV defaults": lambda f: cv2.imencode(".png", f[..., ::-1].copy())[1].tobytes(),
    }
    for fn in coders.values():  # compile / warm up
        fn(frames[0])
    times = {k: [] for k in coders}
    sizes = {k: [] for k in coders}
    for _ in range(a.rounds):
        for name, fn in coders.items():
            for f in frames:
                t = time.perf_counter()
                data = fn(f)
                times[name].append(time.perf_counter() - t)
                sizes[name].append(len(data))
    for name, fn in coders.items():  # every file decodes to the frame
        for f in frames:
            back = cv2.imdecode(np.frombuffer(fn(f), np.uint8), cv2.IMREAD_COLOR)
            if not np.array_equal(back[..., ::-1], f):
                raise SystemExit(f"bench_png: {name} is not lossless")
    h, w = frames[0].shape[:2]
    print(f"{len(frames)} frames {w}x{h}, {a.rounds} interleaved rounds, one core")
    for name in coders:
        print(f"  {name:45s} {statistics.median(times[name]) * 1e3:6.1f} ms  "
              f"{statistics.mean(sizes[name]) / 1e6:5.2f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
