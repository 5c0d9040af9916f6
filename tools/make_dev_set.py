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
into place at the end; an existing OUT is refused unless ``--force``, and ``--force`` replaces
only an empty folder or a collection this tool made (its ``dev_set.json``), never another
folder. Files of SRC that are links to a place outside SRC are refused, never read; OUT is
locked against a second run. Bad input or a full disk: one line, exit status 2. Prints the
images and vehicles per group, and the sim2real plan keys its known sources need
(:data:`SCORING`: UCAS-AOD labels cars only, so large-vehicle predictions there are dropped,
and ignores 20 px of border).
"""

from __future__ import annotations

import math
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from aerial_synth.cli import Parser  # noqa: E402
from aerial_synth.errors import AerialSynthError, ConfigError, OutputError  # noqa: E402
from aerial_synth.evaluate.labels import read_dataset  # noqa: E402
from aerial_synth.formats import dota  # noqa: E402
from aerial_synth.io_utils import (  # noqa: E402
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    check_output_dir,
    is_inside,
    replace_dir,
)
from aerial_synth.out_guard import out_lock, refuse_here, remove_dead_temps  # noqa: E402
from aerial_synth.safe_input import (  # noqa: E402
    MAX_IMAGE_FILE_BYTES,
    check_link,
    decode_image,
    input_roots,
    read_bytes,
    shown,
)

VEHICLES = ("small-vehicle", "large-vehicle")
#: The file that marks OUT as this tool's collection (what ``--force`` may replace).
MARKER = "dev_set.json"
MARKER_FORMAT = "aerial-synth-dev-set/1"
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


def build(src: Path, out: Path, gsd: dict[str, float], classes=VEHICLES,
          jpeg: int | None = None) -> dict[str, list[int]]:
    """Write the collection into ``out`` (a new folder); returns {group: [images, vehicles]}.
    ``jpeg``: lossless images (PNG, TIFF, BMP) re-encoded as JPEG of that quality, to carry the
    set to a GPU machine within its 64 MiB (JPEG files are still copied byte for byte)."""
    with input_roots([src]):  # a label or image linked out of SRC is refused, never read
        layout, items = read_dataset(src, option="SRC")
    if layout != "collection":
        raise ConfigError(f"SRC {shown(src)}: expected a folder of datasets (one sub-folder "
                          f"each), found one {layout} dataset")
    unknown = sorted(set(gsd) - {it.name.split("/", 1)[0] for it in items})
    if unknown:
        raise ConfigError(f"--gsd: no group {', '.join(unknown)} in {shown(src)}")
    counts: dict[str, list[int]] = {}
    for it in items:
        group, stem = it.name.split("/", 1)
        stem = Path(stem).name
        if it.image_path is None:
            raise ConfigError(f"{shown(it.label_path)}: no image beside it")
        with input_roots([src]):
            check_link(it.image_path, ConfigError)  # an image linked out of SRC: not copied
        it.keep_classes(classes)
        g = it.gsd_m if it.gsd_m is not None else gsd.get(group)
        (out / group / "images").mkdir(parents=True, exist_ok=True)
        suffix = it.image_path.suffix.lower()
        if jpeg is not None and suffix not in (".jpg", ".jpeg"):
            _write_jpeg(src, it.image_path, out / group / "images" / (stem + ".jpg"), jpeg)
        else:
            shutil.copyfile(it.image_path, out / group / "images" / (stem + suffix))
        lines = dota.to_lines(dota.from_labels(it), g, it.image_source or group)
        if g is None:
            lines = [ln for ln in lines if not ln.startswith("gsd:")]
        atomic_write_text(out / group / "labelTxt" / (stem + ".txt"),
                          "".join(ln + "\n" for ln in lines))
        c = counts.setdefault(group, [0, 0])
        c[0] += 1
        c[1] += len(it.classes)
    atomic_write_json(out / MARKER, {"format": MARKER_FORMAT, "groups": counts})
    return counts


def _write_jpeg(src: Path, path: Path, dest: Path, quality: int) -> None:
    """``path`` (a lossless image inside ``src``) re-encoded as a JPEG of ``quality`` at ``dest``."""
    import cv2  # only for --jpeg

    with input_roots([src]):
        data = read_bytes(path, f"{shown(path)}", ConfigError, max_bytes=MAX_IMAGE_FILE_BYTES)
    img = decode_image(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    ok, enc = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(quality)]) \
        if img is not None else (False, None)
    if not ok:
        raise ConfigError(f"{shown(path)}: cannot decode it, or re-encode it as JPEG")
    atomic_write_bytes(dest, enc.tobytes())


def replaceable(out: Path) -> bool:
    """True when ``--force`` may replace the existing folder ``out``: it is empty, or it is
    a collection this tool made (its marker file says so)."""
    if not any(out.iterdir()):
        return True
    marker = out / MARKER
    try:
        return marker.is_file() and not marker.is_symlink() and \
            f'"{MARKER_FORMAT}"' in marker.read_bytes()[:4096].decode("utf-8", "replace")  # guard: own marker
    except OSError:
        return False


def _parse_gsd(texts: list[str]) -> dict[str, float]:
    gsd = {}
    for text in texts:
        k, sep, v = text.partition("=")
        try:
            val = float(v)
        except ValueError:
            val = math.nan
        if not (sep and k.strip()) or not math.isfinite(val) or val <= 0:
            raise ConfigError(f"--gsd: expected GROUP=M with M a finite number > 0, got {text!r}")
        gsd[k.strip()] = val
    return gsd


def _check_out(src: Path, out: Path, force: bool) -> None:
    check_output_dir(out, "OUT")  # a folder, or a new path below writable folders
    refuse_here(out, "OUT")  # '.' or a folder above it would be replaced by a sibling
    if is_inside(out, src) or is_inside(src, out):
        raise OutputError(f"OUT {shown(out)}: overlaps SRC {shown(src)}; choose a folder outside it")
    if out.exists() and not force:
        raise OutputError(f"OUT {shown(out)}: exists; choose a new folder or --force")
    if out.exists() and not replaceable(out):
        raise OutputError(f"OUT {shown(out)}: exists and is not a collection made by "
                          f"make_dev_set.py (no {MARKER}); --force replaces only those; "
                          "choose a new folder")


def main(argv=None) -> int:
    ap = Parser(prog="make_dev_set", description=__doc__.split("\n\n")[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--gsd", action="append", default=[], metavar="GROUP=M",
                    help="GSD of a group whose labels carry none (repeatable)")
    ap.add_argument("--jpeg", type=int, default=None, metavar="Q",
                    help="re-encode lossless images as JPEG of quality Q (1-100): the set then fits "
                    "a GPU machine's 64 MiB carry (tools/sim2real_device.sh); default: copies")
    ap.add_argument("--force", action="store_true", help="replace an existing OUT")
    a = ap.parse_args(argv)
    try:
        counts = _run(a)
    except AerialSynthError as e:  # a bad source folder, label file or OUT: one line
        print(f"make_dev_set: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 2
    except OSError as e:  # a full disk, a folder in use, a permission: one line
        where = shown(e.filename) if e.filename is not None else f"OUT {shown(a.out)}"
        print(f"make_dev_set: error: {where}: {e.strerror or type(e).__name__}", file=sys.stderr)
        return 2
    for group, (n_img, n_veh) in sorted(counts.items()):
        print(f"{group}: {n_img} images, {n_veh} vehicles")
    print(f"total: {sum(c[0] for c in counts.values())} images, "
          f"{sum(c[1] for c in counts.values())} vehicles -> {a.out}")
    keys = plan_keys(counts)
    if keys:
        print("sim2real plan keys for this collection (docs/sim2real.md):\n" + keys)
    return 0


def _run(a) -> dict[str, list[int]]:
    gsd = _parse_gsd(a.gsd)
    if a.jpeg is not None and not 1 <= a.jpeg <= 100:
        raise ConfigError(f"--jpeg: expected a quality 1-100, got {a.jpeg}")
    _check_out(a.src, a.out, a.force)
    with out_lock(a.out, "make_dev_set", "OUT"):
        remove_dead_temps(a.out)
        a.out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{a.out.name}.", suffix=".tmp", dir=a.out.parent))
        try:
            counts = build(a.src, tmp, gsd, jpeg=a.jpeg)
            replace_dir(tmp, a.out)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    return counts


if __name__ == "__main__":
    sys.exit(main())
