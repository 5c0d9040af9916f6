"""Property tests for every reader of user files (issue 27): file names with bytes that are
not UTF-8, emoji, control characters and 255-byte names, and documents nested to any depth
(or multiplied through YAML aliases). A reader either reads the file or raises an
:class:`AerialSynthError` with one line; never another exception (RecursionError,
UnicodeEncodeError, OverflowError, cv2.error), never a crash."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aerial_synth.errors import AerialSynthError
from aerial_synth.safe_input import input_roots

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])

# -- strategies ----------------------------------------------------------------------------------

#: one file-name stem: any bytes but "/" and NUL (and not "." / ".."), at most 240 bytes so a
#: suffix still fits 255; biased to the hostile ones
_odd = st.sampled_from([b"\xff\xfe", b"\x80", b"\xc3(", "🚗".encode(), "é".encode(), b"\x1b[2J",
                        b"\n", b"\t", b" ", b"-", b"'", b"\\", b"*", b"?", b"n" * 240])
stems = st.lists(st.one_of(_odd, st.binary(min_size=1, max_size=8)), min_size=1, max_size=6).map(
    lambda parts: b"".join(parts).replace(b"/", b"_").replace(b"\x00", b"_")[:240]).filter(
    lambda s: s not in (b".", b".."))


def _nested(depth: int, kind: str):
    """A document ``depth`` deep: lists, mappings or both alternating."""
    v: object = "x"
    for k in range(depth):
        if kind == "list" or (kind == "mixed" and k % 2):
            v = [v]
        else:
            v = {"k": v}
    return v


depths = st.one_of(st.integers(0, 12), st.integers(90, 110), st.sampled_from([1000, 5000]))
kinds = st.sampled_from(["list", "map", "mixed"])


def _yaml_text(depth: int, kind: str, key: str = "names") -> str:
    # flow style, written by hand: yaml.safe_dump recurses and cannot write 5000 levels
    inner = json.dumps(_nested(min(depth, 200), kind)) if depth <= 200 else (
        "[" * depth + "x" + "]" * depth)
    return f"{key}: {inner}\n"


def _bomb(levels: int, fan: int) -> str:
    lines = ["a0: &a0 [" + ",".join(['"x"'] * fan) + "]"]
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * fan) + "]")
    lines.append("names: [" + ",".join([f"*a{levels - 1}"] * fan) + "]")
    return "\n".join(lines) + "\n"


def _ok_or_one_line(fn, *args, **kw):
    """Call a reader: a result, or an AerialSynthError whose message the CLI prints as one
    line (a file name may hold a newline: the CLI joins the message's lines)."""
    from aerial_synth.cli import _one_line

    try:
        return fn(*args, **kw)
    except AerialSynthError as exc:
        text = _one_line(str(exc))
        assert text and "\n" not in text, text
        text.encode("utf-8", "backslashreplace")
        return None


@pytest.fixture
def tmp(tmp_path):
    """A fresh folder per call: hypothesis runs many examples in one test call."""
    made = []

    class Fresh:
        def __truediv__(self, name):
            d = Path(tempfile.mkdtemp(dir=tmp_path))
            made.append(d)
            return d / name

        def __fspath__(self):
            d = Path(tempfile.mkdtemp(dir=tmp_path))
            made.append(d)
            return str(d)

    yield Fresh()
    for d in made:
        shutil.rmtree(d, ignore_errors=True)


def _write(path_bytes: bytes, data: bytes) -> str:
    with open(path_bytes, "wb") as fh:
        fh.write(data)
    return os.fsdecode(path_bytes)


# -- file names ----------------------------------------------------------------------------------


def _dota_folder(root: Path, stem: bytes) -> Path:
    import cv2

    (root / "images").mkdir(parents=True)
    (root / "labelTxt").mkdir()
    ok, buf = cv2.imencode(".png", np.full((40, 50, 3), 90, np.uint8))
    _write(os.fsencode(root / "images") + b"/" + stem + b".png", buf.tobytes())
    _write(os.fsencode(root / "labelTxt") + b"/" + stem + b".txt",
           b"imagesource:t\ngsd:0.1\n1 1 9 1 9 5 1 5 small-vehicle 0\n")
    return root


@SETTINGS
@given(stem=stems)
def test_dataset_readers_take_any_file_name(tmp, stem):
    from aerial_synth.evaluate.labels import read_dataset, resolve_dota_folder

    root = _dota_folder(tmp / "ds", stem)
    with input_roots([root]):
        res = _ok_or_one_line(read_dataset, root)
        assert res is not None and len(res[1]) == 1 and len(res[1][0]) == 1
        assert os.fsencode(res[1][0].image_path).endswith(stem + b".png")
        lab, img = _ok_or_one_line(resolve_dota_folder, root)
        assert lab == root / "labelTxt"


@SETTINGS
@given(stem=stems)
def test_image_readers_take_any_file_name(tmp, stem):
    import cv2

    from aerial_synth.evaluate.labels import image_size
    from aerial_synth.safe_input import image_file_complete, read_image

    ok, buf = cv2.imencode(".png", np.zeros((7, 5, 3), np.uint8))
    p = _write(os.fsencode(os.fspath(tmp)) + b"/" + stem + b".png", buf.tobytes())
    assert image_size(p) == (5, 7)
    assert read_image(p).shape == (7, 5, 3)
    assert image_file_complete(p, (5, 7))


@SETTINGS
@given(stem=stems)
def test_yaml_and_json_readers_take_any_file_name(tmp, stem):
    from aerial_synth.evaluate.labels import parse_names
    from aerial_synth.formats._common import read_json
    from aerial_synth.placement.config import load_scenario
    from aerial_synth.scene.io import load_rules, load_scene
    from aerial_synth.vehicles.catalog import load_catalog

    base = os.fsencode(os.fspath(tmp)) + b"/" + stem
    y = _write(base + b".yaml", b"names: [a, b]\n")
    assert _ok_or_one_line(parse_names, y) == ["a", "b"]
    _ok_or_one_line(load_rules, y)
    _ok_or_one_line(load_catalog, y)
    _ok_or_one_line(load_scenario, y)
    _ok_or_one_line(load_scene, y)
    j = _write(base + b".json", b'{"a": [1, 2]}')
    assert _ok_or_one_line(read_json, j) == {"a": [1, 2]}
    _ok_or_one_line(load_scene, _write(base + b".obj", b"o ground\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n"))


# -- nested documents ---------------------------------------------------------------------------


@SETTINGS
@given(depth=depths, kind=kinds)
def test_yaml_readers_take_any_nesting(tmp, depth, kind):
    from aerial_synth.evaluate.labels import parse_names
    from aerial_synth.placement.config import load_scenario
    from aerial_synth.scene.io import load_rules, load_scene
    from aerial_synth.vehicles.catalog import load_catalog

    for key, fn in (("names", parse_names), ("rules", load_rules), ("models", load_catalog),
                    ("spacing", load_scenario), ("generator", load_scene)):
        p = tmp / f"{key}.yaml"
        p.write_text(_yaml_text(depth, kind, key))
        _ok_or_one_line(fn, str(p))


@SETTINGS
@given(depth=depths, kind=kinds)
def test_json_readers_take_any_nesting(tmp, depth, kind):
    from aerial_synth.dataset.manifest import read_manifest
    from aerial_synth.formats import meta
    from aerial_synth.formats._common import read_json

    text = ("[" * depth + "]" * depth) if kind == "list" else (
        '{"a":' * depth + "1" + "}" * depth if kind == "map" else json.dumps(
            _nested(min(depth, 500), "mixed")))
    p = tmp / "manifest.json"
    p.write_text(text)
    _ok_or_one_line(read_json, p)
    _ok_or_one_line(meta.read, p)
    assert read_manifest(p.parent) is None  # not a manifest, whatever its depth


@SETTINGS
@given(levels=st.integers(2, 9), fan=st.integers(2, 12))
def test_yaml_aliases_expand_within_the_budget_or_are_refused(tmp, levels, fan):
    from aerial_synth.evaluate.labels import parse_names
    from aerial_synth.safe_input import MAX_NODES, load_yaml

    text = _bomb(levels, fan)
    expanded = sum(fan ** k for k in range(1, levels + 2))  # every list and its items
    try:
        load_yaml(text, "t.yaml")
        assert expanded <= 2 * MAX_NODES
    except AerialSynthError as exc:
        assert "alias" in str(exc) and expanded > MAX_NODES // 2
    p = tmp / "data.yaml"
    p.write_text(text)
    assert _ok_or_one_line(parse_names, str(p)) is None  # names are lists: never "no objects"
