"""Turn a folder of real labelled datasets into the collection ``aerial-synth sim2real --real``
reads: one DOTA-layout group per dataset (``images/``, ``labelTxt/`` with a ``gsd:`` header
where the GSD is known), vehicle boxes only. This is how the development set of docs/gsd.md
and docs/sim2real.md is made from ``../shared/reference/real_samples`` (Minsk drone frames in
DOTA layout, VEDAI tiles, DOTA8 crops in YOLO-OBB, UCAS-AOD Google Earth cars in DOTA layout
with per-image gsd: headers)::

    python tools/make_dev_set.py ../shared/reference/real_samples .s2r/real --gsd vedai=0.25

SRC is anything ``aerial-synth stats`` reads as a collection (DOTA, YOLO-OBB or VEDAI
sub-folders; readers in ``aerial_synth.formats``, class names DOTA-style). ``--gsd GROUP=M``
gives the GSD of a group whose labels carry none (VEDAI's 12.5 cm tiles resampled to 512 px
are 0.25 m); groups without one get no ``gsd:`` header (``sim2real --real-gsd`` then
decides). Images are copied byte for byte. OUT is built in a temporary sibling and renamed
into place at the end; an existing OUT is refused unless ``--force``. Prints the images and
vehicles per group, and the sim2real plan keys its known sources need (:data:`SCORING`:
UCAS-AOD labels cars only, so large-vehicle predictions there are dropped, and ignores 20 px
of border).
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aerial_synth.errors import AerialSynthError  # noqa: E402
from aerial_synth.evaluate.labels import read_dataset  # noqa: E402
from aerial_synth.formats import dota  # noqa: E402
from aerial_synth.io_utils import check_output_dir, is_inside, replace_dir  # noqa: E402

VEHICLES = ("small-vehicle", "large-vehicle")
#: how sim2real must score a known source (printed as plan keys when its group is present):
#: UCAS-AOD labels cars only (its trucks are no false positives) and cars cut by the border only
#: in part (README.txt there); the Minsk drone frames leave cars at the edge unlabelled
SCORING = {"ucas_aod": {"ignore_border": 20, "ignore_classes": ["large-vehicle"]},
           "minsk_uav": {"ignore_border": 40}}


def plan_keys(groups) -> str:
    """The sim2real plan keys (YAML flow style) for the known sources among ``groups``."""
    border = {g: SCORING[g]["ignore_border"] for g in sorted(groups) if "ignore_border" in SCORING.get(g, {})}
    classes = {g: SCORING[g]["ignore_classes"] for g in sorted(groups) if "ignore_classes" in SCORING.get(g, {})}
    parts = []
    if border:
        parts.append("ignore_border: {" + ", ".join(f"{g}: {v}" for g, v in border.items()) + "}")
    if classes:
        parts.append("ignore_classes: {" + ", ".join(f"{g}: [{', '.join(v)}]" for g, v in classes.items()) + "}")
    return "\n".join(parts)


def build(src: Path, out: Path, gsd: dict[str, float], classes=VEHICLES, jpeg: int | None = None) -> dict[str, list[int]]:
    """Write the collection into ``out`` (a new folder); returns {group: [images, vehicles]}.
    ``jpeg``: lossless images (PNG, TIFF, BMP) re-encoded as JPEG of that quality, to carry the
    set to a GPU machine within its 64 MiB (JPEG files are still copied byte for byte)."""
    layout, items = read_dataset(src, option="SRC")
    if layout != "collection":
        raise SystemExit(f"SRC {src}: expected a folder of datasets (one sub-folder each), "
                         f"found one {layout} dataset")
    unknown = sorted(set(gsd) - {it.name.split("/", 1)[0] for it in items})
    if unknown:
        raise SystemExit(f"--gsd: no group {', '.join(unknown)} in {src}")
    counts: dict[str, list[int]] = {}
    for it in items:
        group, stem = it.name.split("/", 1)
        stem = Path(stem).name
        if it.image_path is None:
            raise SystemExit(f"{it.label_path}: no image beside it")
        it.keep_classes(classes)
        g = it.gsd_m if it.gsd_m is not None else gsd.get(group)
        (out / group / "images").mkdir(parents=True, exist_ok=True)
        suffix = it.image_path.suffix.lower()
        if jpeg is not None and suffix not in (".jpg", ".jpeg"):
            import cv2  # only for --jpeg

            img = cv2.imread(str(it.image_path), cv2.IMREAD_COLOR)
            ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)]) if img is not None else (False, None)
            if not ok:
                raise SystemExit(f"{it.image_path}: cannot decode or re-encode it as JPEG")
            (out / group / "images" / (stem + ".jpg")).write_bytes(data.tobytes())
        else:
            shutil.copyfile(it.image_path, out / group / "images" / (stem + suffix))
        lines = dota.to_lines(dota.from_labels(it), g, it.image_source or group)
        if g is None:
            lines = [ln for ln in lines if not ln.startswith("gsd:")]
        (out / group / "labelTxt").mkdir(parents=True, exist_ok=True)
        (out / group / "labelTxt" / (stem + ".txt")).write_text("".join(ln + "\n" for ln in lines),
                                                                 encoding="utf-8")
        c = counts.setdefault(group, [0, 0])
        c[0] += 1
        c[1] += len(it.classes)
    return counts


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--gsd", action="append", default=[], metavar="GROUP=M",
                    help="GSD of a group whose labels carry none (repeatable)")
    ap.add_argument("--jpeg", type=int, default=None, metavar="Q",
                    help="re-encode lossless images as JPEG of quality Q (1-100): the set then fits "
                    "a GPU machine's 64 MiB carry (tools/sim2real_device.sh); default: copies")
    ap.add_argument("--force", action="store_true", help="replace an existing OUT")
    a = ap.parse_args(argv)
    gsd = {}
    for text in a.gsd:
        k, sep, v = text.partition("=")
        try:
            gsd[k.strip()] = float(v)
            ok = bool(sep and k.strip()) and math.isfinite(gsd[k.strip()]) and gsd[k.strip()] > 0
        except ValueError:
            ok = False
        if not ok:
            ap.error(f"--gsd: expected GROUP=M with M a finite number > 0, got {text!r}")
    if a.jpeg is not None and not 1 <= a.jpeg <= 100:
        ap.error(f"--jpeg: expected a quality 1-100, got {a.jpeg}")
    try:
        check_output_dir(a.out, "OUT")  # a folder, or a new path below writable folders
    except AerialSynthError as e:
        ap.error(str(e))
    if is_inside(a.out, a.src) or is_inside(a.src, a.out):
        ap.error(f"OUT {a.out}: overlaps SRC {a.src}; choose a folder outside it")
    if a.out.exists() and not a.force:
        ap.error(f"{a.out}: exists; choose a new folder or --force")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{a.out.name}.", suffix=".tmp", dir=a.out.parent))
    try:
        counts = build(a.src, tmp, gsd, jpeg=a.jpeg)
        replace_dir(tmp, a.out)
    except AerialSynthError as e:  # a bad source folder or label file: one line
        shutil.rmtree(tmp, ignore_errors=True)
        print(f"make_dev_set: {e}", file=sys.stderr)
        return 2
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    for group, (n_img, n_veh) in sorted(counts.items()):
        print(f"{group}: {n_img} images, {n_veh} vehicles")
    print(f"total: {sum(c[0] for c in counts.values())} images, "
          f"{sum(c[1] for c in counts.values())} vehicles -> {a.out}")
    keys = plan_keys(counts)
    if keys:
        print("sim2real plan keys for this collection (docs/sim2real.md):\n" + keys)
    return 0


if __name__ == "__main__":
    sys.exit(main())
