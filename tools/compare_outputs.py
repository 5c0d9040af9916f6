"""Hash what aerial-synth writes, to show a refactor leaves every output byte-identical.

Usage::

    python tools/compare_outputs.py --out hashes.json [--work DIR] [--quick]
    python tools/compare_outputs.py --compare A.json B.json

The first form runs the CLI of the checkout this script lies in (``python -m
aerial_synth.cli`` with that checkout first on ``PYTHONPATH``) with fixed seeds and small
outputs, and writes one JSON object ``{artifact: sha256}``:

- ``scene/<name>``: :meth:`Scene.vertex_hash` of every bundled scene (``list_scenes()``)
  and of the OSM test town (``scene/osm-town``, built from ``tests/scene/osm_town.py``);
- ``place/<scene>/<scenario>/...``: ``placement.json``, ``placement.png`` and the summary
  of ``aerial-synth place``;
- ``export-full/<scene>/<scenario>/...``: every file of ``aerial-synth export`` with
  ``--preset full`` and all four formats (dota, eagle, yolo-obb, coco): images, labels,
  per-image metadata, COCO annotations, data.yaml, manifest and summary;
- ``export-fast/<scene>/<scenario>/...``: the same with ``--preset fast`` (DOTA only);
- ``eval/...``: ``aerial-synth eval`` (voc07 and coco metrics) of deterministically
  perturbed predictions (boxes shifted, scores falling, every 5th box dropped, one false
  positive per image) made from the full city_park/jam export's DOTA labels, against
  that export: eval.json, summary.txt and the PR curves;
- ``variant/<name>/...``: exports beyond one scene and scenario (``--fast`` preset, small
  images, all four formats): a scene mix, a GSD range, an altitude range and a tiled world,
  each with 1 and 2 workers and on Dask (``--dask local:2``): every file as above;
- ``error/...``: the exit status and the one-line message of a run expected to fail
  (``highway`` has no parking lot for the ``parking`` scenario).

Normalised before hashing (they vary legitimately between runs or checkouts):
- absolute paths: the work folder and the checkout's path become ``<WORK>``/``<REPO>``
  in JSON, YAML and text files and in error messages;
- version strings: in JSON, a string value equal to ``aerial_synth.__version__`` under a
  key containing ``version`` becomes ``<version>``; matplotlib's ``Software`` text chunk
  is dropped from the PR-curve PNGs (``pr_*.png``);
- timings: JSON keys that name a duration or a moment (``elapsed_s``, ``seconds``,
  ``created``, ``timestamp``, ``started``, ``finished``, ``wall_s``) are removed; the
  CLI's stdout (which prints timings) is not hashed.
Every other byte is hashed as written: our own PNGs, label text, JSON key order.

``--compare A.json B.json`` lists the artifacts missing on either side and those whose
hashes differ, and exits 1 on any difference (0 when identical); with ``--subset``, B may
be a ``--quick`` or ``--scenes-only`` run (only the artifacts it has are compared).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SEED = 7
#: (scene, scenario) pairs: three scenarios on each of three scenes, plus the depot's lots
#: (the parking scenario needs painted lots: suburb and depot have them).
COMBOS = [("city_park", "jam"), ("city_park", "sparse"), ("city_park", "street-parking"),
          ("suburb", "jam"), ("suburb", "parking"), ("suburb", "sparse"),
          ("highway", "jam"), ("highway", "normal"), ("highway", "sparse"),
          ("depot", "parking")]
QUICK_COMBOS = [("city_park", "jam"), ("suburb", "parking"), ("highway", "sparse")]
EXPORT_ARGS = ["--images", "2", "--size", "512", "--images-per-placement", "2",
               "--seed", str(SEED), "--no-progress", "--workers", "1"]
#: name -> the export's own arguments; each runs with --workers 1, --workers 2 and on Dask
VARIANTS = {
    "mix": ["--scene-mix", "city_park/jam:1,suburb/sparse:1,highway/normal:1",
            "--images", "4", "--images-per-placement", "1"],
    "gsd-range": ["--scene", "highway", "--scenario", "jam", "--gsd", "0.1:0.3",
                  "--images", "3", "--images-per-placement", "2"],
    "altitude-range": ["--scene", "suburb", "--scenario", "sparse", "--altitude", "40:90",
                       "--images", "3", "--images-per-placement", "3"],
    "tiled": ["--scene", "city_park", "--scenario", "jam", "--tile-m", "80",
              "--images", "4", "--images-per-placement", "2"],
}
VARIANT_RUNS = {"w1": ["--workers", "1"], "w2": ["--workers", "2"], "dask": ["--dask", "local:2"]}
_TIME_KEYS = {"elapsed_s", "seconds", "created", "timestamp", "started", "finished", "wall_s"}


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env.setdefault("PYTHONHASHSEED", "0")
    return env


def _cli(args: list[str], work: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "aerial_synth.cli", *args], cwd=work,
                          env=_env(), capture_output=True, text=True)


def _version() -> str:
    out = subprocess.run([sys.executable, "-c", "import aerial_synth; print(aerial_synth.__version__)"],
                         env=_env(), capture_output=True, text=True, check=True)
    return out.stdout.strip()


class Normaliser:
    def __init__(self, work: Path, version: str):
        self.work, self.version = str(work), version

    def text(self, s: str) -> str:
        return s.replace(self.work, "<WORK>").replace(str(REPO), "<REPO>")

    def _json(self, obj, key: str = ""):
        if isinstance(obj, dict):
            return {k: self._json(v, k) for k, v in obj.items() if k not in _TIME_KEYS}
        if isinstance(obj, list):
            return [self._json(v, key) for v in obj]
        if isinstance(obj, str):
            if "version" in key.lower() and obj == self.version:
                return "<version>"
            return self.text(obj)
        return obj

    def file_bytes(self, path: Path) -> bytes:
        raw = path.read_bytes()
        if path.suffix == ".json":
            obj = self._json(json.loads(raw))
            return json.dumps(obj, sort_keys=False, indent=1).encode()
        if path.suffix in (".txt", ".yaml", ".yml", ".csv", ".md"):
            return self.text(raw.decode("utf-8")).encode()
        if path.suffix == ".png" and path.name.startswith("pr_"):
            return _png_without_text(raw)
        return raw


def _png_without_text(raw: bytes) -> bytes:
    """A PNG's bytes without its tEXt/iTXt/zTXt chunks (matplotlib writes its version)."""
    out, i = [raw[:8]], 8
    while i < len(raw):
        (n,) = struct.unpack(">I", raw[i:i + 4])
        kind = raw[i + 4:i + 8]
        if kind not in (b"tEXt", b"iTXt", b"zTXt"):
            out.append(raw[i:i + 12 + n])
        i += 12 + n
    return b"".join(out)


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _hash_tree(root: Path, prefix: str, norm: Normaliser, out: dict) -> None:
    for p in sorted(root.rglob("*")):
        if p.is_file():
            out[f"{prefix}/{p.relative_to(root).as_posix()}"] = _sha(norm.file_bytes(p))


def _run_ok(args: list[str], work: Path, norm: Normaliser, out: dict, key: str) -> bool:
    """Run the CLI; a failure is recorded as ``<key>/FAILED`` (exit status and stderr) and
    reported, so a run that starts or stops failing shows as a difference."""
    r = _cli(args, work)
    if r.returncode != 0:
        print(f"compare_outputs: aerial-synth {' '.join(args)} failed ({r.returncode}): "
              f"{r.stderr.strip()[-500:]}", file=sys.stderr, flush=True)
        out[f"{key}/FAILED"] = _sha(f"{r.returncode}\n{norm.text(r.stderr)}".encode())
        return False
    return True


_SCENES_CODE = """
import json, sys, tempfile
from pathlib import Path
from aerial_synth.scene import load_scene, list_scenes
out = {n: load_scene(n).vertex_hash() for n in list_scenes()}
sys.path.insert(0, sys.argv[1])  # the checkout's tests/: the OSM test town
from scene.osm_town import make_town
from aerial_synth.scene.osm import build_osm_scene
with tempfile.TemporaryDirectory() as d:
    town = make_town().write(Path(d) / "town.osm")
    out["osm-town"] = build_osm_scene(town).vertex_hash()
print(json.dumps(out))
"""


def scene_hashes(out: dict) -> None:
    """Vertex hashes of every bundled scene and of the OSM test town (tests/scene/osm_town.py)."""
    r = subprocess.run([sys.executable, "-c", _SCENES_CODE, str(REPO / "tests")], env=_env(),
                       capture_output=True, text=True, cwd=tempfile.gettempdir())
    if r.returncode != 0:
        raise SystemExit(f"compare_outputs: scene hashes failed: {r.stderr.strip()[-2000:]}")
    for name, h in json.loads(r.stdout.strip().splitlines()[-1]).items():
        out[f"scene/{name}"] = h


def place(scene: str, scenario: str, work: Path, norm: Normaliser, out: dict) -> None:
    d = work / "place" / scene / scenario
    key = f"place/{scene}/{scenario}"
    if _run_ok(["place", "--scene", scene, "--scenario", scenario, "--seed", str(SEED),
                "--out", str(d)], work, norm, out, key):
        _hash_tree(d, key, norm, out)


def export(scene: str, scenario: str, preset: str, work: Path, norm: Normaliser,
           out: dict) -> Path | None:
    d = work / f"export-{preset}" / scene / scenario
    formats = "dota,eagle,yolo-obb,coco" if preset == "full" else "dota"
    key = f"export-{preset}/{scene}/{scenario}"
    if not _run_ok(["export", "--scene", scene, "--scenario", scenario, "--preset", preset,
                    "--format", formats, "--out", str(d), *EXPORT_ARGS], work, norm, out, key):
        return None
    _hash_tree(d, key, norm, out)
    return d


def _perturbed_predictions(export_dir: Path, pred_dir: Path) -> None:
    """DOTA task-1 predictions from an export's labels: shifted, scored, some dropped."""
    per_class: dict[str, list[str]] = {}
    for lab in sorted(export_dir.glob("dota/*/labelTxt/*.txt")):
        k = 0
        for line in lab.read_text(encoding="utf-8").splitlines():
            parts = line.split()
            if len(parts) < 9 or ":" in line:
                continue
            k += 1
            if k % 5 == 0:
                continue  # a miss
            shift = (k % 3) * 0.8
            xy = [float(v) + shift for v in parts[:8]]
            score = max(0.05, 1.0 - 0.03 * k)
            per_class.setdefault(parts[8], []).append(
                f"{lab.stem} {score:.3f} " + " ".join(f"{v:.2f}" for v in xy))
        per_class.setdefault("small-vehicle", []).append(
            f"{lab.stem} 0.500 10 10 40 10 40 25 10 25")  # a false positive
    pred_dir.mkdir(parents=True, exist_ok=True)
    for cls, lines in sorted(per_class.items()):
        (pred_dir / f"Task1_{cls}.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")


def evaluate(export_dir: Path, work: Path, norm: Normaliser, out: dict) -> None:
    pred = work / "eval" / "pred"
    _perturbed_predictions(export_dir, pred)
    _hash_tree(pred, "eval/pred", norm, out)
    for metric in ("voc07", "coco"):
        d = work / "eval" / metric
        if _run_ok(["eval", "--gt", str(export_dir), "--pred", str(pred), "--split", "train",
                    "--metric", metric, "--out", str(d)], work, norm, out, f"eval/{metric}"):
            _hash_tree(d, f"eval/{metric}", norm, out)


def variant(name: str, run: str, work: Path, norm: Normaliser, out: dict) -> None:
    """One of :data:`VARIANTS` run as :data:`VARIANT_RUNS` says (1 or 2 workers, Dask)."""
    d = work / "variant" / name / run
    key = f"variant/{name}/{run}"
    args = ["export", *VARIANTS[name], "--preset", "fast", "--size", "256",
            "--format", "dota,eagle,yolo-obb,coco", "--seed", str(SEED), "--no-progress",
            *VARIANT_RUNS[run], "--out", str(d)]
    if _run_ok(args, work, norm, out, key):
        _hash_tree(d, key, norm, out)


def expected_error(work: Path, norm: Normaliser, out: dict) -> None:
    r = _cli(["place", "--scene", "highway", "--scenario", "parking", "--seed", str(SEED),
              "--out", str(work / "error")], work)
    out["error/highway-parking"] = _sha(f"{r.returncode}\n{norm.text(r.stderr)}".encode())


def run_all(work: Path, quick: bool, scenes_only: bool = False) -> dict:
    norm = Normaliser(work, _version())
    out: dict[str, str] = {}
    scene_hashes(out)
    if scenes_only:
        return dict(sorted(out.items()))
    combos = QUICK_COMBOS if quick else COMBOS
    first = None
    for scene, scenario in combos:
        print(f"  {scene} x {scenario}", file=sys.stderr, flush=True)
        place(scene, scenario, work, norm, out)
        d = export(scene, scenario, "full", work, norm, out)
        first = first or d
        export(scene, scenario, "fast", work, norm, out)
    if first is not None:
        evaluate(first, work, norm, out)
    for name in VARIANTS:
        for run in VARIANT_RUNS:
            print(f"  variant {name} ({run})", file=sys.stderr, flush=True)
            variant(name, run, work, norm, out)
    expected_error(work, norm, out)
    return dict(sorted(out.items()))


def compare(a_path: Path, b_path: Path, subset: bool = False) -> int:
    a = json.loads(a_path.read_text(encoding="utf-8"))
    b = json.loads(b_path.read_text(encoding="utf-8"))
    quick_b = subset and set(b) <= set(a)
    diffs = []
    for k in sorted(set(a) | set(b)):
        if k not in b:
            if not quick_b:
                diffs.append(f"only in {a_path.name}: {k}")
        elif k not in a:
            diffs.append(f"only in {b_path.name}: {k}")
        elif a[k] != b[k]:
            diffs.append(f"differs: {k}")
    compared = len(set(a) & set(b))
    for line in diffs:
        print(line)
    if quick_b and not diffs:
        print(f"{b_path.name} (a --quick or --scenes-only run) is a subset of {a_path.name}")
    print(f"{compared} artifacts compared, {len(diffs)} difference(s)")
    return 1 if diffs else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, help="write {artifact: sha256} JSON here")
    p.add_argument("--work", type=Path, help="keep the outputs in this folder (default: a temp folder)")
    p.add_argument("--quick", action="store_true", help=f"only {len(QUICK_COMBOS)} scene x scenario pairs")
    p.add_argument("--scenes-only", action="store_true", help="only the scene vertex hashes (seconds)")
    p.add_argument("--compare", nargs=2, type=Path, metavar=("A.json", "B.json"))
    p.add_argument("--subset", action="store_true",
                   help="with --compare: B is a --quick or --scenes-only run (A's other artifacts "
                   "are not missing)")
    args = p.parse_args(argv)
    if args.compare:
        return compare(*args.compare, subset=args.subset)
    if args.out is None:
        p.error("--out is required unless --compare")
    tmp = None
    if args.work is None:
        tmp = Path(tempfile.mkdtemp(prefix="compare_outputs_"))
        work = tmp
    else:
        work = args.work.resolve()
        if work.exists():
            shutil.rmtree(work)
        work.mkdir(parents=True)
    try:
        hashes = run_all(work, args.quick, args.scenes_only)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    args.out.write_text(json.dumps(hashes, indent=1) + "\n", encoding="utf-8")
    print(f"{len(hashes)} artifacts hashed -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
