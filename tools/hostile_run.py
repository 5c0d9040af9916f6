"""A hostile user's run of ``aerial-synth``: several hundred cases of bad values, damaged or
odd files and odd paths, none of them the ones of issue 27, each judged by the project's
contract for bad input:

- exit status 0 (accepted) or 2 (refused); never a traceback, a crash or a hang;
- a refusal is one line on stderr, starting ``aerial-synth``; an accepted run prints
  nothing on stderr but ``aerial-synth: warning:`` lines (no libpng/OpenCV/numpy noise);
- a refused run leaves no ``--out`` it did not find;
- where a case says ``refuse``, accepting it is a failure too (a NaN is never a value).

Cases run in a worker process that calls ``aerial_synth.cli.main`` in-process (file
descriptors 1 and 2 captured per case, so native libraries' lines are seen too); a case
that crashes or hangs (``--timeout``) costs one worker, which is restarted.

    python tools/hostile_run.py                 # this checkout: tried / behaved / left
    python tools/hostile_run.py --against DIR   # and DIR (e.g. the commit before the fixes):
                                                # fixed = misbehaved there, behave here
    python tools/hostile_run.py -v              # every misbehaving case, with its output

Prints the counts; exit status 1 when a case misbehaves.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# -- fixtures ------------------------------------------------------------------------------------


def _png(path: Path, w: int, h: int, value: int = 90, channels: int = 3, depth: int = 8) -> None:
    import cv2
    import numpy as np

    dtype = np.uint16 if depth == 16 else np.uint8
    shape = (h, w) if channels == 1 else (h, w, channels)
    ok, buf = cv2.imencode(".png", np.full(shape, value, dtype))
    path.write_bytes(buf.tobytes())


def _dota(root: Path, n: int = 2, size=(160, 120), prefix: str = "r") -> Path:
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "labelTxt").mkdir(parents=True, exist_ok=True)
    for i in range(n):
        _png(root / "images" / f"{prefix}{i:03d}.png", *size)
        (root / "labelTxt" / f"{prefix}{i:03d}.txt").write_text(
            "imagesource:t\ngsd:0.12\n10 10 30 10 30 20 10 20 small-vehicle 0\n"
            "50 50 90 50 90 70 50 70 large-vehicle 0\n")
    return root


def _obj(path: Path) -> Path:
    lines, off = [], 0
    for name, (x0, y0, x1, y1, z) in {"ground": (-40, -40, 40, 40, 0.0),
                                      "road_ew": (-40, -4, 40, 4, 0.05)}.items():
        lines.append(f"o {name}")
        lines += [f"v {x} {y} {z}" for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
        lines += [f"f {off + 1} {off + 2} {off + 3}", f"f {off + 1} {off + 3} {off + 4}"]
        off += 4
    path.write_text("\n".join(lines) + "\n")
    return path


def _variant(base: Path, name: str, edit) -> Path:
    """A copy of DOTA folder ``base`` as ``name``, changed by ``edit(folder)``."""
    d = base.parent / name
    shutil.copytree(base, d, symlinks=True)
    edit(d)
    return d


def build_fixtures(root: Path) -> dict:
    """The inputs the cases use (small: every accepted case stays cheap)."""
    F: dict = {}
    R = _dota(root / "R")
    S = _dota(root / "S", prefix="s")
    F["R"], F["S"], F["obj"] = R, S, _obj(root / "tiny.obj")
    lab = "labelTxt/r000.txt"
    img = "images/r000.png"

    def label(text):
        return lambda d: (d / lab).write_bytes(text if isinstance(text, bytes) else text.encode())

    label_cases = {
        "nul": b"imagesource:t\ngsd:0.12\n10 10 30 10 30 20 10\x0020 small-vehicle 0\n",
        "crlf": "imagesource:t\r\ngsd:0.12\r\n10 10 30 10 30 20 10 20 small-vehicle 0\r\n",
        "bom": "\ufeffimagesource:t\ngsd:0.12\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "utf16": "imagesource:t\n10 10 30 10 30 20 10 20 small-vehicle 0\n".encode("utf-16"),
        "latin1": "imagesource:caf\xe9\n10 10 30 10 30 20 10 20 small-vehicle 0\n".encode("latin-1"),
        "long_line": "1 " * 500_000 + "\n",
        "tabs": "10\t10\t30\t10\t30\t20\t10\t20\tsmall-vehicle\t0\n",
        "negative": "-10 -10 -3 -10 -3 -5 -10 -5 small-vehicle 0\n",
        "zero_area": "10 10 10 10 10 10 10 10 small-vehicle 0\n",
        "collinear": "10 10 20 10 30 10 40 10 small-vehicle 0\n",
        "nan": "nan 10 30 10 30 20 10 20 small-vehicle 0\n",
        "inf": "10 inf 30 10 30 20 10 20 small-vehicle 0\n",
        "comma_decimal": "10,5 10 30 10 30 20 10 20 small-vehicle 0\n",
        "eleven_fields": "10 10 30 10 30 20 10 20 small-vehicle 0 extra\n",
        "eight_fields": "10 10 30 10 30 20 10 20\n",
        "difficult_minus": "10 10 30 10 30 20 10 20 small-vehicle -1\n",
        "difficult_float": "10 10 30 10 30 20 10 20 small-vehicle 1.0\n",
        "difficult_word": "10 10 30 10 30 20 10 20 small-vehicle yes\n",
        "unicode_class": "10 10 30 10 30 20 10 20 véhicule 0\n",
        "gsd_negative": "imagesource:t\ngsd:-1\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "gsd_zero": "imagesource:t\ngsd:0\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "gsd_nan": "imagesource:t\ngsd:nan\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "gsd_huge": "imagesource:t\ngsd:1e400\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "gsd_word": "imagesource:t\ngsd:twelve\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "control_source": "imagesource:\x1b[31mred\x07\n10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "blank_only": "\n\n\n   \n",
        "binary": bytes(range(256)) * 4,
        "huge_coord_1e6": "1e6 10 30 10 30 20 10 20 small-vehicle 0\n",
        "hex_coord": "0x10 10 30 10 30 20 10 20 small-vehicle 0\n",
        "underscore_coord": "1_0 10 30 10 30 20 10 20 small-vehicle 0\n",
        "many_boxes": "10 10 30 10 30 20 10 20 small-vehicle 0\n" * 20000,
        "bidi_class": "10 10 30 10 30 20 10 20 car\u202egnp.exe 0\n",
    }
    F["labels"] = {k: _variant(R, f"R_{k}", label(v)) for k, v in label_cases.items()}

    def image(fn):
        return lambda d: fn(d / img)

    def jpg_as_png(p):
        import cv2
        import numpy as np

        p.write_bytes(cv2.imencode(".jpg", np.full((120, 160, 3), 90, np.uint8))[1].tobytes())

    def dir_named(p):
        p.unlink()
        p.mkdir()

    def fifo(p):
        p.unlink()
        os.mkfifo(p)

    def dangling(p):
        p.unlink()
        p.symlink_to(p.parent / "nowhere.png")

    def loop(p):
        p.unlink()
        p.symlink_to(p)

    image_cases = {
        "empty": lambda p: p.write_bytes(b""),
        "text": lambda p: p.write_text("not an image\n"),
        "jpg_bytes": jpg_as_png,
        "one_px": lambda p: _png(p, 1, 1),
        "gray": lambda p: _png(p, 160, 120, channels=1),
        "rgba": lambda p: _png(p, 160, 120, channels=4),
        "sixteen_bit": lambda p: _png(p, 160, 120, value=40000, depth=16),
        "other_size": lambda p: _png(p, 16, 12),
        "header_only": lambda p: p.write_bytes(p.read_bytes()[:33]),
        "signature_only": lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n"),
        "zero_width_header": lambda p: p.write_bytes(
            b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x00\x00\x00\x00\x00\x10\x08\x02\x00\x00\x00"
            b"\x00\x00\x00\x00" + p.read_bytes()[33:]),
        "directory": dir_named,
        "fifo": fifo,
        "dangling_link": dangling,
        "link_loop": loop,
    }
    F["images"] = {k: _variant(R, f"I_{k}", image(v)) for k, v in image_cases.items()}

    def folder(fn):
        return fn

    def no_images(d):
        shutil.rmtree(d / "images")

    def label_dir(d):
        (d / "labelTxt" / "r000.txt").unlink()
        (d / "labelTxt" / "r000.txt").mkdir()

    def label_fifo(d):
        (d / "labelTxt" / "r000.txt").unlink()
        os.mkfifo(d / "labelTxt" / "r000.txt")

    def label_dangling(d):
        (d / "labelTxt" / "r000.txt").unlink()
        (d / "labelTxt" / "r000.txt").symlink_to(d / "gone.txt")

    def labels_file(d):
        shutil.rmtree(d / "labelTxt")
        (d / "labelTxt").write_text("I am a file\n")

    def orphan_label(d):
        (d / "labelTxt" / "zzz.txt").write_text("10 10 30 10 30 20 10 20 small-vehicle 0\n")

    def upper_ext(d):
        os.rename(d / "images" / "r000.png", d / "images" / "r000.PNG")

    def dir_link_out(d):
        (d / "labelTxt").rename(d.parent / f"{d.name}_outside_labels")
        (d / "labelTxt").symlink_to(d.parent / f"{d.name}_outside_labels")

    def thousand_empty(d):
        for i in range(1000):
            (d / "labelTxt" / f"e{i:04d}.txt").write_text("")

    folder_cases = {"no_images": no_images, "label_is_dir": label_dir, "label_fifo": label_fifo,
                    "label_dangling": label_dangling, "labelTxt_is_file": labels_file,
                    "orphan_label": orphan_label, "upper_ext": upper_ext,
                    "labelTxt_links_out": dir_link_out, "thousand_empty": thousand_empty}
    F["folders"] = {k: _variant(R, f"D_{k}", folder(v)) for k, v in folder_cases.items()}

    yaml_cases = {
        "python_tag": "names: !!python/object/apply:os.system ['true']\n",
        "binary_tag": "names: !!binary aGVsbG8=\n",
        "dup_keys": "names: [a]\nnames: [b]\n",
        "int_overflow": "names: [a]\nnc: 1e400\n",
        "merge_key": "base: &b {names: [a, b]}\n<<: *b\n",
        "self_alias": "a: &a [*a]\nnames: *a\n",
        "tabs": "names:\n\t- a\n",
        "top_list": "- a\n- b\n",
        "top_scalar": "hello\n",
        "empty": "",
        "bom": "\ufeffnames: [a]\n",
        "utf16": "names: [a]\n",  # written as UTF-16 below
        "nul": "names: [a\x00b]\n",
        "long_string": "names: [" + "a" * 1_000_000 + "]\n",
        "key_list": "[1, 2]: x\nnames: [a]\n",
        "names_int_keys_gap": "names: {0: a, 2: b}\n",
        "names_negative": "names: {-1: a}\n",
        "names_empty_list": "names: []\n",
        "names_spaces": "names: ['small vehicle', ' ']\n",
        "names_dup": "names: [a, a]\n",
        "date_value": "names: [2024-01-01]\n",
        "unclosed": "names: [a, b\n",
        "document_stream": "names: [a]\n---\nnames: [b]\n",
        "anchor_wide": "a: &a [" + ",".join(["x"] * 2000) + "]\nnames: [" + ",".join(["*a"] * 600) + "]\n",
    }
    F["yaml"] = {}
    for k, text in yaml_cases.items():
        p = root / "yaml" / f"{k}.yaml"
        p.parent.mkdir(exist_ok=True)
        if k == "utf16":
            p.write_bytes(text.encode("utf-16"))
        else:
            p.write_bytes(text.encode("utf-8", "surrogatepass"))
        F["yaml"][k] = p

    obj_cases = {
        "empty": "",
        "nan_vertex": "o road\nv nan 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n",
        "huge_vertex": "o road\nv 1e300 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n",
        "bad_face": "o road\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n",
        "no_faces": "o road\nv 0 0 0\nv 1 0 0\n",
        "words": "this is not an obj\n",
        "binary": bytes(range(256)).decode("latin-1"),
        "no_road": "o ground\nv 0 0 0\nv 10 0 0\nv 10 10 0\nf 1 2 3\n",
        "negative_index": "o road\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf -1 -2 -9\n",
    }
    F["obj"] = F["obj"]
    F["objs"] = {}
    for k, text in obj_cases.items():
        p = root / "objs" / f"{k}.obj"
        p.parent.mkdir(exist_ok=True)
        p.write_text(text, encoding="latin-1")
        F["objs"][k] = p
    for k, text in {"ply_garbage": "ply\nformat nonsense\n", "glb_garbage": "glTF\x02\x00\x00\x00",
                    "gltf_not_json": "{not json", "gltf_empty_json": "{}",
                    "gltf_deep": "[" * 100000 + "]" * 100000}.items():
        ext = {"ply_garbage": ".ply", "glb_garbage": ".glb"}.get(k, ".gltf")
        p = root / "objs" / f"{k}{ext}"
        p.write_text(text, encoding="latin-1")
        F["objs"][k] = p

    spec_cases = {
        "neg_size": "generator: city_park\nsize_m: [-10, 10]\nseed: 1\n",
        "huge_size": "generator: city_park\nsize_m: [1e9, 1e9]\nseed: 1\n",
        "nan_size": "generator: city_park\nsize_m: [.nan, 10]\nseed: 1\n",
        "unknown_gen": "generator: moon_base\nsize_m: [60, 60]\n",
        "seed_string": "generator: city_park\nsize_m: [60, 60]\nseed: abc\n",
        "seed_negative": "generator: city_park\nsize_m: [60, 60]\nseed: -5\n",
        "seed_huge": "generator: city_park\nsize_m: [60, 60]\nseed: 99999999999999999999999999\n",
        "size_three": "generator: city_park\nsize_m: [60, 60, 60]\n",
        "unknown_key": "generator: city_park\nsize_m: [60, 60]\nwarp: 9\n",
        "size_bool": "generator: city_park\nsize_m: [true, 60]\n",
    }
    F["specs"] = {}
    for k, text in spec_cases.items():
        p = root / "specs" / f"{k}.yaml"
        p.parent.mkdir(exist_ok=True)
        p.write_text(text)
        F["specs"][k] = p

    P = root / "P"
    P.mkdir()
    (P / "Task1_small-vehicle.txt").write_text("r000 0.9 10 10 30 10 30 20 10 20\n")
    F["P"] = P
    pred_cases = {
        "score_nan": "r000 nan 10 10 30 10 30 20 10 20\n",
        "score_word": "r000 high 10 10 30 10 30 20 10 20\n",
        "unknown_image": "zzz 0.9 10 10 30 10 30 20 10 20\n",
        "nine_fields": "r000 0.9 10 10 30 10 30 20 10\n",
        "negative_score": "r000 -5 10 10 30 10 30 20 10 20\n",
        "empty": "",
        "binary": "\x00\x01\x02",
        "many": "r000 0.5 10 10 30 10 30 20 10 20\n" * 50000,
    }
    F["preds"] = {}
    for k, text in pred_cases.items():
        d = root / f"P_{k}"
        d.mkdir()
        (d / "Task1_small-vehicle.txt").write_text(text)
        F["preds"][k] = d
    e = root / "P_no_files"
    e.mkdir()
    F["preds"]["no_files"] = e
    d = root / "P_space_class"
    d.mkdir()
    (d / "Task1_small vehicle.txt").write_text("r000 0.9 10 10 30 10 30 20 10 20\n")
    F["preds"]["space_class"] = d
    d = root / "P_empty_class"
    d.mkdir()
    (d / "Task1_.txt").write_text("r000 0.9 10 10 30 10 30 20 10 20\n")
    F["preds"]["empty_class"] = d
    def osm(nodes, ways="", rels=""):
        body = "".join(f"<node id='{i}' lat='{la}' lon='{lo}'/>" for i, la, lo in nodes)
        return f"<?xml version='1.0'?><osm version='0.6'>{body}{ways}{rels}</osm>\n"

    road = "<way id='{i}'>{nds}<tag k='highway' v='residential'/>{tags}</way>"

    def way(i, refs, tags=""):
        return road.format(i=i, nds="".join(f"<nd ref='{r}'/>" for r in refs), tags=tags)

    two = [(1, 0, 0), (2, 0, 0.001)]
    osm_cases = {
        "lat_1e300": osm([(1, "1e300", 0), (2, 0, 0.001)], way(3, [1, 2])),
        "lat_nan": osm([(1, "nan", 0), (2, 0, 0.001)], way(3, [1, 2])),
        "lat_91": osm([(1, 91, 0), (2, 0, 0.001)], way(3, [1, 2])),
        "missing_node": osm([(2, 0, 0.001)], way(3, [1, 2])),
        "near_pole": osm([(1, 89.9999, 0), (2, 89.9999, 179)], way(3, [1, 2])),
        "around_the_globe": osm([(1, 0, -179), (2, 0, 179)], way(3, [1, 2])),
        "width_1e300": osm(two, way(3, [1, 2], "<tag k='width' v='1e300'/>")),
        "width_negative": osm(two, way(3, [1, 2], "<tag k='width' v='-5'/>")),
        "lanes_huge": osm(two, way(3, [1, 2], "<tag k='lanes' v='99999999'/>")),
        "lanes_word": osm(two, way(3, [1, 2], "<tag k='lanes' v='many'/>")),
        "oneway_odd": osm(two, way(3, [1, 2], "<tag k='oneway' v='-1'/><tag k='oneway' v='yes'/>")),
        "one_node_way": osm(two, way(3, [1])),
        "self_loop": osm(two, way(3, [1, 1, 1])),
        "negative_ids": osm([(-1, 0, 0), (-2, 0, 0.001)], way(-3, [-1, -2])),
        "relation_cycle": osm(two, way(3, [1, 2]),
                              "<relation id='5'><member type='relation' ref='5' role=''/>"
                              "<tag k='type' v='multipolygon'/></relation>"),
        "building_height_1e308": osm(two + [(4, 0.0005, 0), (5, 0.0005, 0.0005), (6, 0.0004, 0.0005)],
                                     way(3, [1, 2]) + "<way id='7'><nd ref='4'/><nd ref='5'/>"
                                     "<nd ref='6'/><nd ref='4'/><tag k='building' v='yes'/>"
                                     "<tag k='height' v='1e308'/></way>"),
        "empty_file": "",
        "not_xml": "hello\n",
        "no_version": "<osm><node id='1' lat='0' lon='0'/></osm>\n",
        "entity_bomb": "<?xml version='1.0'?><!DOCTYPE osm [<!ENTITY a 'aaaaaaaaaa'>"
                       "<!ENTITY b '&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;'>]><osm version='0.6'>"
                       "<node id='1' lat='0' lon='0'><tag k='name' v='&b;'/></node></osm>\n",
    }
    F["osm"] = {}
    for k, text in osm_cases.items():
        p = root / "osm" / f"{k}.osm"
        p.parent.mkdir(exist_ok=True)
        p.write_text(text)
        F["osm"][k] = p
    for k, data in {"bz2_garbage": (".osm.bz2", b"BZh91AY&SY garbage"),
                    "pbf_garbage": (".osm.pbf", b"\x00\x00\x00\x0dgarbage"),
                    "pbf_empty": (".osm.pbf", b"")}.items():
        p = root / "osm" / f"{k}{data[0]}"
        p.write_bytes(data[1])
        F["osm"][k] = p

    F["file"] = root / "afile.txt"
    F["file"].write_text("x\n")
    F["fifo"] = root / "afifo"
    os.mkfifo(F["fifo"])
    return F


# -- cases ---------------------------------------------------------------------------------------


def cases(F: dict, scratch: Path) -> list[dict]:
    """(name, argv, expect, out) for every case: expect "refuse" (exit 2, one line),
    "ok" (exit 0) or "either"."""
    out: list[dict] = []
    n = [0]

    def add(name, argv, expect="either", out_path=True):
        n[0] += 1
        o = scratch / f"o{n[0]:04d}"
        argv = [str(a) for a in argv]
        if out_path:
            argv += ["--out", str(o)]
        out.append({"name": name, "argv": argv, "expect": expect,
                    "out": str(o) if out_path else None})

    R, S, P, obj = F["R"], F["S"], F["P"], F["obj"]
    bad_numbers = ["-1", "0", "nan", "inf", "-inf", "1e400", "1e-400", "0x10", "", " ", "1_000",
                   "true", "½", "٣", "1e18", "2.5", "--", "１"]

    # numeric options of the cheap commands (each value refused or accepted, never a crash)
    mix_base = ["mix", "--real", R, "--synthetic", S, "--real-images", "1"]
    for opt in ("--tile", "--keep-threshold", "--val-fraction", "--real-gsd", "--seed",
                "--synthetic-images"):
        for v in bad_numbers:
            extra = ["--tile", "100"] if opt == "--keep-threshold" else []
            add(f"mix {opt} {v!r}", mix_base + extra + [opt, v],
                "refuse" if v in ("nan", "inf", "-inf", "1e400", "", " ", "true", "--") else "either")
    for v in bad_numbers:
        add(f"mix --real-fraction {v!r}", ["mix", "--real", R, "--synthetic", S, "--real-fraction", v],
            "refuse" if v in ("nan", "inf", "-inf", "-1", "1e400", "", "true", "--") else "either")
    for opt in ("--max-images", "--gsd", "--seed"):
        for v in bad_numbers:
            add(f"stats {opt} {v!r}", ["stats", R, opt, v],
                "refuse" if v in ("nan", "inf", "-inf", "1e400", "", "true", "--") else "either")
    for opt in ("--iou",):
        for v in bad_numbers:
            add(f"eval {opt} {v!r}", ["eval", "--gt", R, "--pred", P, opt, v],
                "refuse" if v in ("nan", "inf", "-inf", "1e400", "-1", "", "true", "--") else "either")
    for opt in ("--limit", "--thumb"):
        for v in ("-1", "0", "nan", "1e400", "100000", "abc"):
            add(f"show {opt} {v!r}", ["show", R, opt, v],
                "refuse" if v in ("nan", "1e400", "abc", "-1") else "either")
    for v in ("-1", "0", "nan", "1e400", "0.001", "1e5", "abc"):
        add(f"scene show --m-per-px {v!r}", ["scene", "show", obj, "--m-per-px", v],
            "refuse" if v in ("-1", "nan", "1e400", "abc") else "either", out_path=False)

    # label file contents
    for k, d in F["labels"].items():
        add(f"stats on label {k}", ["stats", d])
        add(f"eval on label {k}", ["eval", "--gt", d, "--pred", P], out_path=False)
        add(f"mix on label {k}", ["mix", "--real", d, "--synthetic", S, "--real-fraction", "1",
                                  "--val-fraction", "0", "--tile", "100", "--overlap", "0"])
        add(f"show on label {k}", ["show", d])
    # image files
    for k, d in F["images"].items():
        add(f"stats on image {k}", ["stats", d])
        add(f"mix on image {k}", ["mix", "--real", d, "--synthetic", S, "--real-fraction", "1",
                                  "--val-fraction", "0", "--tile", "100", "--overlap", "0"])
        add(f"show on image {k}", ["show", d])
    # folder layouts
    for k, d in F["folders"].items():
        add(f"stats on folder {k}", ["stats", d])
        add(f"eval on folder {k}", ["eval", "--gt", d, "--pred", P], out_path=False)
        add(f"mix on folder {k}", ["mix", "--real", d, "--synthetic", S, "--real-images", "1"])
        add(f"show on folder {k}", ["show", d])
    # YAML documents as --names, --catalog, --labels, --scenario, scene spec
    for k, y in F["yaml"].items():
        add(f"eval --names {k}", ["eval", "--gt", R, "--pred", P, "--pred-format", "yolo-obb",
                                  "--names", y], out_path=False)
        add(f"assets list --catalog {k}", ["assets", "list", "--catalog", y], out_path=False)
        add(f"scene show --labels {k}", ["scene", "show", obj, "--labels", y, "--out",
                                         scratch / f"lab_{k}.png"], out_path=False)
        add(f"place --scenario {k}", ["place", "--scene", obj, "--scenario", y, "--vehicles", "2",
                                      "--no-png"])
    # meshes and specs as scenes
    for k, p in F["objs"].items():
        add(f"scene show mesh {k}", ["scene", "show", p, "--out", scratch / f"mesh_{k}.png"],
            out_path=False)
    for k, p in F["specs"].items():
        add(f"scene show spec {k}", ["scene", "show", p, "--out", scratch / f"spec_{k}.png"],
            out_path=False)
    # OpenStreetMap extracts
    for k, p in F["osm"].items():
        add(f"scene from-osm {k}", ["scene", "from-osm", p, "--no-cache", "--out",
                                    scratch / f"osm_{k}.glb"], out_path=False)
        add(f"scene from-osm {k} --bbox", ["scene", "from-osm", p, "--no-cache", "--bbox",
                                           "0,0,0.001,0.001", "--out", scratch / f"osmb_{k}.glb"],
            out_path=False)
    # prediction folders
    for k, d in F["preds"].items():
        add(f"eval --pred {k}", ["eval", "--gt", R, "--pred", d], out_path=False)
    for v in ("dota", "yolo", "Task1", "", "auto "):
        add(f"eval --pred-format {v!r}", ["eval", "--gt", R, "--pred", P, "--pred-format", v],
            "refuse", out_path=False)
    for v in ("", ",", "a,,b", " ", "all,small-vehicle"):
        add(f"stats --classes {v!r}", ["stats", R, "--classes", v])
    # paths: --out and inputs
    for k, o in {"slash_root": "/", "proc": "/proc/self/nope", "dash": "-", "dot_dot": "..",
                 "trailing_slash": str(scratch / "ts") + "/", "long_component": str(scratch / ("x" * 300)),
                 "long_path": str(scratch) + "/" + "/".join(["d" * 200] * 25), "file": str(F["file"]),
                 "fifo": str(F["fifo"]), "newline": str(scratch / "a\nb"), "tilde": "~nouser/x"}.items():
        for cmd in (["stats", R], ["mix", "--real", R, "--synthetic", S, "--real-images", "1"],
                    ["show", R]):
            add(f"{cmd[0]} --out {k}", cmd + ["--out", o], "refuse" if k in (
                "slash_root", "proc", "long_component", "long_path", "file", "fifo") else "either",
                out_path=False)
    for k, i in {"missing": scratch / "missing", "file": F["file"], "fifo": F["fifo"], "dash": "-",
                 "empty": "", "root": "/proc/self/fd"}.items():
        exp = "either" if k == "dash" else "refuse"  # "-" is a folder an earlier case may make
        add(f"stats input {k}", ["stats", i], exp)
        add(f"show input {k}", ["show", i], exp)
        add(f"mix --real {k}", ["mix", "--real", i, "--synthetic", S, "--real-images", "1"], exp)
        add(f"eval --gt {k}", ["eval", "--gt", i, "--pred", P], exp, out_path=False)
    # same folder given twice, and an output beside its own lock
    add("mix real == synthetic", ["mix", "--real", R, "--synthetic", R, "--real-images", "1"])
    add("stats DIR == --compare", ["stats", R, "--compare", R])
    add("mix --out named like a lock", ["mix", "--real", R, "--synthetic", S, "--real-images", "1",
                                        "--out", scratch / ".x.aerial-synth-lock"], out_path=False)
    return out


# -- the worker: cases in-process, fds 1 and 2 captured -------------------------------------------

WORKER = r"""
import json, os, sys, tempfile
sys.argv = ["aerial-synth"]
os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
from aerial_synth.cli import main
result_fd = os.dup(1)
for stream in (sys.stdout, sys.stderr):
    stream.reconfigure(errors="backslashreplace")
for line in sys.stdin:
    case = json.loads(line)
    os.chdir(case["cwd"])
    with tempfile.TemporaryFile() as o, tempfile.TemporaryFile() as e:
        sys.stdout.flush(); sys.stderr.flush()
        s1, s2 = os.dup(1), os.dup(2)
        os.dup2(o.fileno(), 1); os.dup2(e.fileno(), 2)
        try:
            code = main(case["argv"])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
        except BaseException as exc:
            import traceback
            traceback.print_exc()
            code = 1
        sys.stdout.flush(); sys.stderr.flush()
        os.dup2(s1, 1); os.dup2(s2, 2); os.close(s1); os.close(s2)
        o.seek(0); e.seek(0)
        out = o.read()[-2000:].decode("utf-8", "backslashreplace")
        err = e.read().decode("utf-8", "backslashreplace")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    os.write(result_fd, (json.dumps({"code": code, "out": out, "err": err[:4000],
                                     "lines": [ln[:200] for ln in lines[:20]],
                                     "nlines": len(lines)}) + "\n").encode())
"""


class Worker:
    def __init__(self, pythonpath: Path):
        env = dict(os.environ, PYTHONPATH=str(pythonpath), OPENCV_LOG_LEVEL="SILENT")
        self.p = subprocess.Popen([sys.executable, "-c", WORKER], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
                                  cwd=str(pythonpath))
        self.buf = b""

    def run(self, case: dict, timeout: float) -> dict:
        self.p.stdin.write((json.dumps(case) + "\n").encode())
        self.p.stdin.flush()
        end = time.monotonic() + timeout
        while b"\n" not in self.buf:
            left = end - time.monotonic()
            if left <= 0:
                self.kill()
                return {"code": "hang", "out": "", "err": "", "lines": [], "nlines": 0}
            r, _, _ = select.select([self.p.stdout], [], [], left)
            if r:
                chunk = os.read(self.p.stdout.fileno(), 65536)
                if not chunk:
                    code = self.p.wait()
                    return {"code": f"died {code}", "out": "", "err": "", "lines": [], "nlines": 0}
                self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        return json.loads(line)

    def kill(self):
        try:
            self.p.kill()
            self.p.wait(5)
        except Exception:
            pass


def judge(case: dict, res: dict, out_existed: bool) -> str | None:
    """None when the case behaved, else why not."""
    code, err = res["code"], res["err"]
    lines = res.get("lines", [])
    if not isinstance(code, int):
        return str(code)
    if "Traceback" in err:
        return "traceback"
    if code not in (0, 2):
        return f"exit {code}"
    if code == 2:
        if case["expect"] == "ok":
            return "refused"
        if res.get("nlines", 0) != 1 or not lines[0].startswith("aerial-synth"):
            return f"{res.get('nlines', 0)} lines on stderr"
        if case["out"] and not out_existed and os.path.lexists(case["out"]):
            return "left --out behind"
    else:
        if case["expect"] == "refuse":
            return "accepted"
        noise = [ln for ln in lines if not ln.startswith("aerial-synth: warning:")]
        if noise:
            return f"noise on stderr: {noise[0][:80]!r}"
    return None


#: What ``show --out /`` writes into / when a checkout accepts it (removed after the run
#: when the run made them).
_ROOT_LEFTOVERS = ("/r000.jpg", "/r001.jpg", "/contact_sheet.jpg")


def run_all(pythonpath: Path, timeout: float, verbose: bool, limit: int | None) -> dict:
    base = Path(tempfile.mkdtemp(prefix="hostile-run-"))
    there = {p for p in _ROOT_LEFTOVERS if os.path.lexists(p)}
    try:
        F = build_fixtures(base / "fx")
        scratch = base / "scratch"
        scratch.mkdir()
        todo = cases(F, scratch)[:limit]
        results = {}
        w = Worker(pythonpath)
        for case in todo:
            existed = bool(case["out"]) and os.path.lexists(case["out"])
            res = w.run(dict(case, cwd=str(scratch)), timeout)
            if not isinstance(res["code"], int):
                w = Worker(pythonpath)
            why = judge(case, res, existed)
            results[case["name"]] = why
            if verbose and why:
                print(f"MISBEHAVED {case['name']}: {why}\n  argv: {case['argv']}\n  stderr: "
                      f"{res['err'][-600:]!r}", file=sys.stderr)
        w.kill()
        return results
    finally:
        shutil.rmtree(base, ignore_errors=True)
        for p in _ROOT_LEFTOVERS:
            if p not in there and os.path.isfile(p):
                os.unlink(p)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--against", type=Path, default=None,
                    help="another checkout (its aerial_synth/) to count the cases fixed since")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds a case may take (60)")
    ap.add_argument("--limit", type=int, default=None, help="the first N cases only")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args(argv)
    here = run_all(REPO, args.timeout, args.verbose, args.limit)
    tried = len(here)
    left = sorted(k for k, v in here.items() if v)
    print(f"tried {tried}, behaved {tried - len(left)}, left {len(left)}")
    if args.against is not None:
        before = run_all(args.against.resolve(), args.timeout, False, args.limit)
        bad_before = {k for k, v in before.items() if v}
        fixed = sorted(k for k in bad_before if not here.get(k))
        print(f"against {args.against}: misbehaved there {len(bad_before)}, fixed {len(fixed)}, "
              f"misbehave in both {len(bad_before & set(left))}, new here "
              f"{len(set(left) - bad_before)}")
        for k in fixed:
            print(f"  fixed: {k}: was {before[k]}")
    for k in left:
        print(f"  left: {k}: {here[k]}")
    return 1 if left else 0


if __name__ == "__main__":
    sys.exit(main())
