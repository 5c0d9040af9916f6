"""Write the cross-machine fingerprints of the bundled procedural scenes that
tests/scene/test_portability.py compares with (tests/scene/data/fingerprints/<name>.json).

Run after a deliberate change of a generator's geometry, then review the diff:

    .venv/bin/python tools/pin_scene_fingerprints.py [name ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from aerial_synth.io_utils import atomic_write_text
from aerial_synth.out_guard import out_lock
from aerial_synth.scene import load_scene
from aerial_synth.scene.fingerprint import scene_fingerprint

OUT = Path(__file__).resolve().parent.parent / "tests" / "scene" / "data" / "fingerprints"
BUNDLED = ("city_park", "suburb", "highway", "residential_us", "residential_eu", "rural")


def main(names: list[str]) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    with out_lock(OUT, "pin_scene_fingerprints", "OUT"):
        for name in names or BUNDLED:
            _pin(name)


def _pin(name: str) -> None:
    fp = scene_fingerprint(load_scene(name))
    path = atomic_write_text(OUT / f"{name}.json", json.dumps(fp, indent=1) + "\n")
    print(f"{path}: {len(fp['objects'])} objects, layout {fp['layout']['sha256'][:16]}")


if __name__ == "__main__":
    main(sys.argv[1:])
