"""Print how closely the ``warp`` backend agrees with ``raycast`` (CPU, 256 px): scenes x
scenarios x both presets, the figures of :func:`aerial_synth.render.agreement.sweep` and the
tolerances they are held to (tests/render/test_warp_backend.py runs the same sweep, slow).

    .venv/bin/python tools/warp_agreement.py [--frames 2] [--size 256] [--shade device]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aerial_synth.io_utils import atomic_write_text  # noqa: E402
from aerial_synth.out_guard import out_lock  # noqa: E402
from aerial_synth.render.agreement import SWEEP_PAIRS, TOLERANCES, sweep  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--shade", choices=("auto", "host", "device"), default="auto",
                    help="the warp backend's per-pixel stages: numba on the host or its own "
                    "Warp kernels (auto: device kernels on CUDA only)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    from aerial_synth.render.backends import warp as wb

    wb.SHADE = a.shade
    t = time.perf_counter()
    got = sweep(SWEEP_PAIRS, frames=a.frames, size_px=a.size, device=a.device)
    s = got.summary()
    s["seconds"] = round(time.perf_counter() - t, 1)
    s["shade"] = a.shade
    s["tolerances"] = TOLERANCES
    s["failures"] = got.failures()
    for r in got.rows:
        print(json.dumps(r))
    print(json.dumps(s, indent=1))
    if a.json:
        with out_lock(a.json, "warp_agreement", "--json"):
            atomic_write_text(a.json, json.dumps({**s, "rows": got.rows}, indent=1) + "\n")
    return 1 if s["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
