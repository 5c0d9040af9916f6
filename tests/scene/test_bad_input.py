"""Every bad scene input gets one line naming the file and the field (issue 10).

Tables of (input, expected message) for scene specs, label-rules files and mesh files, and
the scene CLI's options and output checks.
"""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
import yaml

from aerial_synth.errors import AerialSynthError, SceneError
from aerial_synth.scene import load_scene
from aerial_synth.scene.procedural import generate

from .conftest import quad_yup, write_glb

CITY_PARK_MIN = {"generator": "city_park", "seed": 1, "size_m": [60, 60],
                 "roads": [{"name": "a", "points": [[-30, 0], [30, 0]], "width_m": 7}]}
SUBURB_MIN = {"generator": "suburb", "size_m": [100, 100], "grid": {"blocks_x": 2, "blocks_y": 2}}
HIGHWAY_MIN = {"generator": "highway", "size_m": [300, 200], "highway": {"lanes": 1}}


def _with(base, path, value):
    """Copy of a spec with ``value`` at ``path`` (a tuple of keys/indices)."""
    import copy

    spec = copy.deepcopy(base)
    node = spec
    for k in path[:-1]:
        node = node[k]
    if value is _DEL:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return spec


_DEL = object()

# (base spec, path, value, expected message after "<file>: ")
SPEC_CASES = [
    (CITY_PARK_MIN, ("seed",), -5, "seed: expected a non-negative integer, got -5"),
    (CITY_PARK_MIN, ("seed",), 1.5, "seed: expected a non-negative integer, got 1.5"),
    (CITY_PARK_MIN, ("seed",), True, "seed: expected a non-negative integer, got True"),
    (CITY_PARK_MIN, ("size_m",), ["abc", 100],
     "size_m: expected [a, b]: 2 finite numbers > 0 and <= 20000, got ['abc', 100]"),
    (CITY_PARK_MIN, ("size_m",), [0, 100],
     "size_m: expected [a, b]: 2 finite numbers > 0 and <= 20000, got [0, 100]"),
    (CITY_PARK_MIN, ("size_m",), [float("nan"), 100],
     "size_m: expected [a, b]: 2 finite numbers > 0 and <= 20000, got [nan, 100]"),
    (CITY_PARK_MIN, ("size_m",), 100,
     "size_m: expected [a, b]: 2 finite numbers > 0 and <= 20000, got 100"),
    (CITY_PARK_MIN, ("size_m",), _DEL, "size_m: missing; expected [width, height] in metres"),
    (CITY_PARK_MIN, ("generator",), "town",
     "generator: expected one of city_park, suburb, highway"),
    (CITY_PARK_MIN, ("name",), 5, "name: expected a non-empty text, got 5"),
    (CITY_PARK_MIN, ("colour",), "red", "top level: unknown key(s) colour; expected one of"),
    (CITY_PARK_MIN, ("roads", 0, "width_m"), -7,
     "roads[0].width_m: expected a finite number > 0 and <= 200, got -7"),
    (CITY_PARK_MIN, ("roads", 0, "width_m"), "wide",
     "roads[0].width_m: expected a finite number > 0 and <= 200, got 'wide'"),
    (CITY_PARK_MIN, ("roads", 0, "lanes"), -1,
     "roads[0].lanes: expected an integer >= 0 and <= 16, got -1"),
    (CITY_PARK_MIN, ("roads", 0, "centre"), "zigzag",
     "roads[0].centre: expected one of dashed, solid, none, got 'zigzag'"),
    (CITY_PARK_MIN, ("roads", 0, "oneway"), "yes", "roads[0].oneway: expected true or false, got 'yes'"),
    (CITY_PARK_MIN, ("roads", 0, "points"), [[0, 0]],
     "roads[0].points: expected a list of >= 2 [x, y] points (metres), got [[0, 0]]"),
    (CITY_PARK_MIN, ("roads", 0, "points"), [[0, 0], [0, 0]],
     "roads[0].points: expected a centre line at least 0.5 m long, got 0 m"),
    (CITY_PARK_MIN, ("roads", 0, "points"), [[0, 0], [0, 2.2e-309]],  # found by the fuzz test
     "roads[0].points: expected a centre line at least 0.5 m long, got 2.2e-309 m"),
    (CITY_PARK_MIN, ("roads", 0, "points"), [[0, 31], [0, 40]],  # beside the 60 m scene
     "roads[0] ('a'): expected a road that crosses the scene (x in [-30, 30] m, y in [-30, 30] m"),
    (CITY_PARK_MIN, ("roads", 0, "points"), [[0, 0], [1, "x"]],
     "roads[0].points[1]: expected [a, b]: 2 finite numbers"),
    (CITY_PARK_MIN, ("roads", 0, "start_on"), "nowhere",
     "roads[0].start_on: expected the name of an earlier road (none yet), got 'nowhere'"),
    (CITY_PARK_MIN, ("roads", 0, "lenght"), 3, "roads[0]: unknown key(s) lenght"),
    (CITY_PARK_MIN, ("roads",), "a road", "roads: expected a list (at most 1000 items), got 'a road'"),
    (CITY_PARK_MIN, ("buildings",), {"count": 10**9},
     "buildings.count: expected an integer >= 0 and <= 20000, got 1000000000"),
    (CITY_PARK_MIN, ("markings",), {"dash_m": 0},
     "markings.dash_m: expected a finite number >= 0.5 and <= 1000, got 0"),
    (CITY_PARK_MIN, ("trees",), {"park": {"count": 3, "crown_radius_m": [5, 2]}},
     "trees.park.crown_radius_m: expected [min, max] with min <= max, got [5, 2]"),
    (CITY_PARK_MIN, ("lakes",), [{"center": [0, 0], "radii_m": [0, 1]}],
     "lakes[0].radii_m: expected [a, b]: 2 finite numbers > 0 and <= 10000, got [0, 1]"),
    (CITY_PARK_MIN, ("poles",), {"spacing_m": float("inf")},
     "poles.spacing_m: expected a finite number >= 0.5 and <= 10000, got inf"),
    (CITY_PARK_MIN, ("tree_subdivisions",), 9,
     "tree_subdivisions: expected an integer >= 0 and <= 4, got 9"),
    (SUBURB_MIN, ("grid",), _DEL, "grid: missing; the suburb generator needs it"),
    (SUBURB_MIN, ("grid", "blocks_x"), 0, "grid.blocks_x: expected an integer >= 1 and <= 50, got 0"),
    (SUBURB_MIN, ("grid", "cul_de_sac"), {"street": 9},
     "grid.cul_de_sac.street: expected an index below 1, got 9"),
    (SUBURB_MIN, ("houses",), {"driveway_prob": 2},
     "houses.driveway_prob: expected a finite number >= 0 and <= 1, got 2"),
    (SUBURB_MIN, ("parking_lots",), [{"center": [0, 0]}], "parking_lots[0]: missing key 'size_m'"),
    (HIGHWAY_MIN, ("highway",), _DEL, "highway: missing; the highway generator needs it"),
    (HIGHWAY_MIN, ("highway", "lanes"), 0, "highway.lanes: expected an integer >= 1 and <= 16, got 0"),
    (HIGHWAY_MIN, ("highway", "junction_x_m"), ["a"],
     "highway.junction_x_m[0]: expected a finite number >= -100000 and <= 100000, got 'a'"),
    (HIGHWAY_MIN, ("highway", "local_roads"), {"north_m": -3},
     "highway.local_roads.north_m: expected a finite number > 0 and <= 100000, got -3"),
]


@pytest.mark.parametrize("base, path, value, expected", SPEC_CASES,
                         ids=[".".join(map(str, c[1])) + f"={c[2]!r}"[:30] for c in SPEC_CASES])
def test_spec_field_errors(tmp_path, base, path, value, expected):
    spec = _with(base, path, value)
    f = tmp_path / "bad_spec.yaml"
    f.write_text(yaml.safe_dump(spec))
    with pytest.raises(SceneError) as ei:
        load_scene(f)
    msg = str(ei.value)
    assert "\n" not in msg
    assert msg.startswith(f"{f}: {expected}"), msg


def test_minimal_specs_are_valid():
    """The bases of the table above are valid, so each case fails for its one field."""
    for base in (CITY_PARK_MIN, SUBURB_MIN):
        sc = generate(base, source="t")
        assert sc.n_triangles > 0 and any(o.label == "road" for o in sc.objects)


def test_seed_override_is_checked():
    with pytest.raises(SceneError, match=r"seed: expected a non-negative integer, got -1"):
        load_scene("city_park", seed=-1)
    assert generate(CITY_PARK_MIN, seed=0).meta["seed"] == 0


def test_geometry_failure_is_one_line(tmp_path):
    # valid fields, impossible together: a local road inside the highway's clearance
    spec = _with(HIGHWAY_MIN, ("highway", "local_roads"), {"north_m": 5, "clear_m": 15})
    with pytest.raises(SceneError) as ei:
        generate(spec, source="hw.yaml")
    assert str(ei.value).startswith("hw.yaml: the highway generator cannot build this spec")
    assert "\n" not in str(ei.value)


# ------------------------------------------------------------------------ label rules
LABEL_CASES = [
    ("label_config: 5\n", "label_config: expected a mapping of key: value, got 5"),
    ("include_defaults: maybe\n", "include_defaults: expected true or false, got 'maybe'"),
    ("rules: [{match: 5, label: road}]\n",
     "rules[0].match: expected a glob or 're:' pattern (text), got 5"),
    ("rules: [{match: 'a*', label: highway_lane}]\n", "rules[0].label: expected one of unknown, road"),
    ("rules: [{match: 'a*', label: road, material: chrome}]\n",
     "rules[0].material: expected one of default, asphalt"),
    ("rules: [{match: 'a*', label: road, color: [1, 2]}]\n",
     "rules[0].color: expected a list of 3 finite numbers, got [1, 2]"),
    ("rules: [{match: 'a*', label: road, color: [2, 0, 0]}]\n",
     "rules[0].color: expected [r, g, b] in 0..1, got [2, 0, 0]"),
    ("rules: [{match: 'a*', label: road, colour: red}]\n", "rules[0]: unknown key(s) colour"),
    ("rules: [{match: 'a*'}]\n", "rules[0]: missing key 'label'"),
    ("rules: [road]\n", "rules[0]: expected a mapping with 'match' and 'label', got 'road'"),
    ("rules: 5\n", "rules: expected a list of rules or a mapping pattern: label, got 5"),
    ("rules: {'a*': 7}\n", "rules['a*'].label: expected one of unknown, road"),
    ("rules: [{match: 're:(', label: road}]\n", "label rule 're:(': expected a regular expression"),
    ("units: -1\n", "units: expected a number of metres per file unit (> 0) or one of cm"),
    ("units: parsecs\n", "units: expected a number of metres per file unit (> 0) or one of cm"),
    ("units: true\n", "units: expected a number of metres per file unit (> 0) or one of cm"),
    ("up_axis: x\n", "up_axis: expected y or z, got 'x'"),
    ("up_axis: 1\n", "up_axis: expected y or z, got 1"),
    ("default_label: 7\n", "default_label: expected one of unknown, road"),
    ("label_config: {road: road}\n", "label_config.road: expected a list of label names, got 'road'"),
    ("label_config: {road: [7]}\n", "label_config.road: expected a list of label names, got [7]"),
    ("label_config: {roads: []}\n", "label_config: unknown key(s) roads"),
    ("label_config: {drivable: [road], obstacles: [road]}\n",
     "label config: labels ['road'] are both drivable and obstacles"),
    ("crs: 5\n", "crs: expected a CRS string such as 'EPSG:32632', got 5"),
    ("crs: nowhere\n", "crs: expected a CRS that pyproj knows (e.g. 'EPSG:32632'), got 'nowhere'"),
    ("rulez: []\n", "top level: unknown key(s) rulez; expected one of crs, default_label"),
    ("[1, 2]\n", "expected a mapping with keys such as 'rules', got [1, 2]"),
]


@pytest.mark.parametrize("text, expected", LABEL_CASES, ids=[c[0].strip()[:30] for c in LABEL_CASES])
def test_label_rules_field_errors(tmp_path, text, expected):
    from aerial_synth.scene.io import load_rules

    f = tmp_path / "bad.labels.yaml"
    f.write_text(text)
    with pytest.raises(SceneError) as ei:
        load_rules(f)
    msg = str(ei.value)
    assert "\n" not in msg
    assert msg.startswith(f"label rules {f}: {expected}"), msg


def test_nan_vertex_in_a_glb_road(tmp_path):
    v, f = quad_yup(0, 10, 0, 10)
    v[2, 0] = np.nan
    glb = write_glb(tmp_path / "nan.glb", [("road", v, f, None)])
    with pytest.raises(SceneError) as ei:
        load_scene(glb)
    assert str(ei.value) == (
        f"scene file {glb}: mesh 'road': expected finite vertex coordinates, got "
        f"[nan, 0.0, -10.0] at vertex 2"
    )


def test_nan_node_transform(tmp_path):
    T = np.eye(4)
    T[0, 3] = np.inf
    glb = write_glb(tmp_path / "inf.glb", [("road", *quad_yup(0, 10, 0, 10), T)])
    with pytest.raises(AerialSynthError, match=r"inf\.glb: node 'road': transform is not finite"):
        load_scene(glb)


def test_labels_file_with_a_procedural_scene_is_refused(tmp_path):
    rules = tmp_path / "broken.yaml"
    rules.write_text("rules: [ {match: road*\n")
    for scene in ("city_park", str(tmp_path / "spec.yaml")):
        (tmp_path / "spec.yaml").write_text(yaml.safe_dump(CITY_PARK_MIN))
        with pytest.raises(SceneError) as ei:
            load_scene(scene, labels=rules)
        assert str(ei.value).startswith(f"--labels {rules}: label rules apply to mesh files")


# ------------------------------------------------------------------------ CLI
def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("cmd", ["show", "export"])
@pytest.mark.parametrize("value", ["-1", "abc", "1.5"])
def test_scene_seed_option(cli_main, capsys, tmp_path, cmd, value):
    out = tmp_path / ("x.png" if cmd == "show" else "x.glb")
    assert cli_main(["scene", cmd, "city_park", "--out", str(out), "--scene-seed", value]) == 2
    line = _one_error_line(capsys)
    assert f"--scene-seed: expected a non-negative integer, got '{value}'" in line
    assert not out.exists()


def test_add_scene_args_scene_seed_is_checked(capsys):
    """The --scene-seed of place/render/export (add_scene_args) refuses -1 in one line."""
    from aerial_synth.cli import Parser
    from aerial_synth.scene.cli import add_scene_args

    p = Parser(prog="aerial-synth place")
    add_scene_args(p)
    assert p.parse_args(["--scene-seed", "0"]).scene_seed == 0
    with pytest.raises(SystemExit) as ei:
        p.parse_args(["--scene-seed", "-1"])
    assert ei.value.code == 2
    assert _one_error_line(capsys) == (
        "aerial-synth place: --scene-seed: expected a non-negative integer, got '-1' "
        "(see 'aerial-synth place --help')"
    )


def test_labels_with_procedural_scene_cli(cli_main, capsys, tmp_path):
    rules = tmp_path / "broken.yaml"
    rules.write_text("rules: [ {match: road*\n")
    out = tmp_path / "map.png"
    assert cli_main(["scene", "show", "city_park", "--labels", str(rules), "--out", str(out)]) == 2
    assert "--labels" in _one_error_line(capsys)
    assert not out.exists()


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "abc", "1000", "0.001"])
def test_m_per_px_option(cli_main, capsys, tmp_path, value):
    out = tmp_path / "map.png"
    assert cli_main(["scene", "show", "city_park", "--out", str(out), "--m-per-px", value]) == 2
    assert (f"--m-per-px: expected a finite number >= 0.01 and <= 100, got '{value}'"
            in _one_error_line(capsys))
    assert not out.exists()


def test_m_per_px_too_fine_for_the_scene(cli_main, capsys, tmp_path):
    out = tmp_path / "map.png"
    assert cli_main(["scene", "show", "city_park", "--out", str(out), "--m-per-px", "0.05"]) == 2
    line = _one_error_line(capsys)
    # the map covers the scene's bounds (505 m x 507 m: tree crowns reach past the edge)
    assert "--m-per-px: 0.05 gives a 10133x10094 px map of city_park (507 m x 505 m); " \
           "expected at least 0.0633 m/px (at most 8000 px a side)" in line, line
    assert not out.exists()


def _device(path):
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except OSError:
        os.mkfifo(path)
    return path


def _bad_outputs(tmp_path, name):
    (tmp_path / "afile").write_text("keep")
    (tmp_path / "adir").mkdir()
    return {
        "device": _device(tmp_path / name),
        "folder": tmp_path / "adir",
        "below_a_file": tmp_path / "afile" / name,
    }


@pytest.mark.parametrize("cmd, name", [("show", "map.png"), ("export", "scene.glb")])
@pytest.mark.parametrize("kind", ["device", "folder", "below_a_file"])
def test_output_checked_before_loading(cli_main, capsys, tmp_path, cmd, name, kind):
    out = _bad_outputs(tmp_path, name)[kind]
    mode = os.lstat(out).st_mode if os.path.lexists(out) else None
    # an unknown scene would be reported if it were loaded first: the output comes first
    assert cli_main(["scene", cmd, "atlantis", "--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert line.startswith(f"aerial-synth: error: --out {out}"), line
    assert "atlantis" not in line
    if mode is not None:
        assert os.lstat(out).st_mode == mode  # the device / folder is still there
    assert (tmp_path / "afile").read_text() == "keep"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder(cli_main, capsys, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert cli_main(["scene", "show", "city_park", "--out", str(ro / "m.png")]) == 2
        assert "not writable" in _one_error_line(capsys)
    finally:
        ro.chmod(0o755)


@pytest.mark.parametrize("cmd", ["place", "render", "export"])
def test_scene_seed_on_every_command(capsys, tmp_path, cmd):
    from aerial_synth.cli import main

    out = tmp_path / "out"
    assert main([cmd, "--scene-seed", "-1", "--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert line.startswith(f"aerial-synth {cmd}: --scene-seed: expected a non-negative integer, "
                           f"got '-1'"), line
    assert not out.exists()


def test_float32_far_glb_warns_in_one_line(cli_main, capsys, tmp_path):
    v, f = quad_yup(500_000 - 20, 500_000 + 20, 5_300_000 - 4, 5_300_000 + 4)
    glb = write_glb(tmp_path / "baked.glb", [("road", v, f, None)])
    out = tmp_path / "m.png"
    assert cli_main(["scene", "show", str(glb), "--out", str(out), "--m-per-px", "0.5"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"aerial-synth: warning: scene file {glb}: "
                                               "vertex coordinates up to 5300004 m"), err
    assert out.stat().st_size > 0


@pytest.mark.parametrize("spec, expected", [
    ({"generator": "depot", "size_m": [240, 200], "road_width_m": -3},
     "road_width_m: expected a finite number > 0 and <= 200, got -3"),
    ({"generator": "depot", "size_m": [240, 200], "garage": {"size_m": [3, 3]}},
     "garage: missing key 'center'"),
    ({"generator": "depot", "size_m": [240, 200], "yards": [{"center": [0, 0], "size_m": [-1, 5]}]},
     "yards[0].size_m: expected [a, b]: 2 finite numbers > 0"),
    ({"generator": "city", "size_km": 0.3, "blocks": 4}, "top level: unknown key(s) blocks"),
    ({"generator": "city", "size_km": 0.3, "markings": {"dash_m": -1}},
     "markings.dash_m: expected a finite number >= 0.5"),
])
def test_other_generators_fields(spec, expected):
    with pytest.raises(SceneError) as ei:
        generate(spec, source="g.yaml")
    assert str(ei.value).startswith(f"g.yaml: {expected}"), str(ei.value)
