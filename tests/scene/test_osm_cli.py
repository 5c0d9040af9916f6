"""OSM scenes from the command line: scene from-osm, --scene FILE.osm with --bbox/--crs,
the cache, the attribution, and bad input (one line, exit status 2, nothing written)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from .osm_town import make_town, to_lonlat

pytest.importorskip("osmium")
pytest.importorskip("pyproj")


@pytest.fixture(scope="module")
def town_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("osmcli")
    t = make_town()
    return {"osm": t.write(d / "town.osm"), "pbf": t.write(d / "town.osm.pbf"),
            "bz2": t.write(d / "town.osm.bz2")}


@pytest.fixture
def cache(tmp_path, monkeypatch):
    c = tmp_path / "cache"
    monkeypatch.setenv("AERIAL_SYNTH_CACHE", str(c))
    return c


def _bbox(x0, y0, x1, y1) -> str:
    a = to_lonlat(x0, y0)
    b = to_lonlat(x1, y1)
    return f"{a[0]:.7f},{a[1]:.7f},{b[0]:.7f},{b[1]:.7f}"


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("aerial-synth: error: ")
    return err[0]


def test_from_osm_writes_a_georeferenced_glb_and_caches(cli_main, town_files, tmp_path, cache,
                                                        capsys):
    from aerial_synth.scene.hints import road_hints
    from aerial_synth.scene.io import load_scene

    out = tmp_path / "town.glb"
    assert cli_main(["scene", "from-osm", str(town_files["pbf"]), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "© OpenStreetMap contributors" in text and "EPSG:32633" in text
    back = load_scene(out)
    assert back.crs == "EPSG:32633"
    assert road_hints(back) is not None
    assert len(list(cache.rglob("*.pkl"))) == 1
    # same file and options: served from the cache (same scene), no second entry
    out2 = tmp_path / "again.glb"
    assert cli_main(["scene", "from-osm", str(town_files["pbf"]), "--out", str(out2)]) == 0
    assert out2.read_bytes() == out.read_bytes()
    assert len(list(cache.rglob("*.pkl"))) == 1
    # another bbox is another entry
    assert cli_main(["scene", "from-osm", str(town_files["pbf"]), "--out", str(out2),
                     "--bbox", _bbox(-150, -150, 150, 150)]) == 0
    assert len(list(cache.rglob("*.pkl"))) == 2


def test_damaged_cache_entry_is_rebuilt(town_files, tmp_path):
    from aerial_synth.scene.osm import build_osm_scene, load_osm_scene

    c = tmp_path / "c"
    a = load_osm_scene(town_files["osm"], cache=c)
    (entry,) = c.glob("*.pkl")
    entry.write_bytes(b"not a pickle")
    b = load_osm_scene(town_files["osm"], cache=c)
    assert b.vertex_hash() == a.vertex_hash() == build_osm_scene(town_files["osm"]).vertex_hash()
    assert entry.read_bytes() != b"not a pickle"


def test_scene_show_draws_the_attribution(cli_main, town_files, tmp_path, cache):
    import cv2

    png = tmp_path / "map.png"
    assert cli_main(["scene", "show", str(town_files["osm"]), "--out", str(png),
                     "--m-per-px", "1"]) == 0
    img = cv2.imread(str(png))
    corner = img[-20:-8, -200:-8]
    white = (corner == 255).all(axis=2).mean()
    dark = (corner < 80).all(axis=2).mean()
    assert white > 0.35 and dark > 0.05  # a white box with black text
    # a scene without attribution has none there
    from aerial_synth.scene.mapview import draw_attribution

    blank = np.zeros((50, 300, 3), np.uint8)
    draw_attribution(blank, "© OpenStreetMap contributors")
    assert (blank[-20:-8, -200:-8] == 255).all(axis=2).mean() > 0.35


def test_place_takes_an_osm_file_and_writes_lonlat(town_files, tmp_path, cache, capsys):
    import pyproj

    from aerial_synth.cli import main

    out = tmp_path / "place"
    rc = main(["place", "--scene", str(town_files["bz2"]), "--bbox", _bbox(-290, -290, 290, 290),
               "--scenario", "sparse", "--vehicles", "25", "--seed", "4", "--out", str(out),
               "--no-png"])
    assert rc == 0, capsys.readouterr().err
    data = json.loads((out / "placement.json").read_text())
    assert data["georeference"]["crs"] == "EPSG:32633"
    o = np.array(data["georeference"]["origin"][:2])
    tr = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32633", always_xy=True)
    for v in data["vehicles"]:
        x, y = tr.transform(v["lon_deg"], v["lat_deg"])
        assert abs(x - o[0] - v["x_m"]) < 0.01 and abs(y - o[1] - v["y_m"]) < 0.01


def _bad_cases(tmp, files):
    good = str(files["osm"])
    bad_xml = tmp / "broken.osm"
    bad_xml.write_text("<?xml version='1.0'?><osm version='0.6'><node id='1' lat='52' "
                       "lon='13'></osm")
    trunc = tmp / "cut.osm.pbf"
    data = files["pbf"].read_bytes()
    trunc.write_bytes(data[: len(data) // 2])
    trunc_bz2 = tmp / "cut.osm.bz2"
    data = files["bz2"].read_bytes()
    trunc_bz2.write_bytes(data[: len(data) // 2])
    empty = tmp / "empty.osm"
    empty.write_text("")
    nothing = tmp / "nothing.osm"
    nothing.write_text("<?xml version='1.0'?><osm version='0.6'></osm>\n")
    park = _bbox(-270, 180, -140, 270)  # the park and its trees: data, but no road
    negative = tmp / "unsaved.osm"  # JOSM's ids for objects never uploaded
    negative.write_text(files["osm"].read_text().replace('id="', 'id="-')
                        .replace('ref="', 'ref="-'))
    return {
        "malformed_xml": (["scene", "from-osm", str(bad_xml)], "cannot read as OSM XML"),
        "truncated_pbf": (["scene", "from-osm", str(trunc)], "cannot read as PBF"),
        "truncated_bz2": (["scene", "from-osm", str(trunc_bz2)], "cannot read as OSM XML (bzip2)"),
        "empty_file": (["scene", "from-osm", str(empty)], "cannot read as OSM XML"),
        "no_data_in_file": (["scene", "from-osm", str(nothing)], "no map data in the file"),
        "bbox_no_data": (["scene", "from-osm", good, "--bbox", "1,1,1.01,1.01"],
                         "no map data inside bbox"),
        "bbox_no_road": (["scene", "from-osm", good, "--bbox", park], "no drivable road"),
        "unknown_crs": (["scene", "from-osm", good, "--crs", "EPSG:999999"], "unknown CRS"),
        "crs_garbage": (["scene", "from-osm", good, "--crs", "utm please"], "unknown CRS"),
        "geographic_crs": (["scene", "from-osm", good, "--crs", "EPSG:4326"], "projected CRS"),
        "bbox_min_gt_max": (["scene", "from-osm", good, "--bbox", "13.41,52.51,13.39,52.53"],
                            "MINLON < MAXLON"),
        "bbox_out_of_range": (["scene", "from-osm", good, "--bbox", "13,52,190,53"],
                              "within [-180, 180]"),
        "bbox_lat_range": (["scene", "from-osm", good, "--bbox", "13,-95,14,53"],
                           "within [-85, 85]"),
        "bbox_not_numbers": (["scene", "from-osm", good, "--bbox", "a,b,c,d"], "four numbers"),
        "bbox_three_numbers": (["scene", "from-osm", good, "--bbox", "1,2,3"], "four numbers"),
        "bbox_nan": (["scene", "from-osm", good, "--bbox", "nan,1,2,3"], "four numbers"),
        "missing_file": (["scene", "from-osm", str(tmp / "nope.osm.pbf")], "file not found"),
        "not_glb": (["scene", "from-osm", good, "--out-ext", ".png"], "ending in .glb"),
        "bbox_on_bundled_scene": (["scene", "show", "city_park", "--bbox", "1,2,3,4"],
                                  "apply to OSM extracts"),
        "labels_with_osm": (["scene", "show", good, "--labels", str(tmp / "l.yaml")],
                            "label rules apply to mesh files"),
        "negative_ids": (["scene", "from-osm", str(negative)], "negative node ids"),
    }


CASES = ["malformed_xml", "truncated_pbf", "truncated_bz2", "empty_file", "no_data_in_file",
         "bbox_no_data", "bbox_no_road", "unknown_crs", "crs_garbage", "geographic_crs",
         "bbox_min_gt_max", "bbox_out_of_range", "bbox_lat_range", "bbox_not_numbers",
         "bbox_three_numbers", "bbox_nan", "missing_file", "not_glb", "bbox_on_bundled_scene",
         "labels_with_osm", "negative_ids"]


@pytest.mark.parametrize("case", CASES)
def test_bad_input_one_line_exit_2_nothing_written(case, cli_main, town_files, tmp_path, cache,
                                                   capsys):
    src = tmp_path / "src"
    src.mkdir()
    argv, expect = _bad_cases(src, town_files)[case]
    outdir = tmp_path / "out"
    outdir.mkdir()
    if "--out-ext" in argv:
        i = argv.index("--out-ext")
        argv = argv[:i] + ["--out", str(outdir / f"scene{argv[i + 1]}")]
    else:
        argv = argv + ["--out", str(outdir / ("scene.glb" if argv[1] == "from-osm" else "map.png"))]
    assert cli_main(argv) == 2
    line = _one_error_line(capsys)
    assert expect in line, line
    assert list(outdir.iterdir()) == []
    assert not cache.exists() or not list(cache.rglob("*.pkl"))


def test_stale_cache_object_is_rebuilt(town_files, tmp_path):
    import pickle

    from aerial_synth.scene.osm import load_osm_scene

    c = tmp_path / "c"
    a = load_osm_scene(town_files["osm"], cache=c)
    (entry,) = c.glob("*.pkl")
    entry.write_bytes(pickle.dumps({"not": "a scene"}))
    b = load_osm_scene(town_files["osm"], cache=c)
    assert b.vertex_hash() == a.vertex_hash()
    assert isinstance(pickle.loads(entry.read_bytes()), type(a))


def test_place_tiled_takes_an_osm_file_with_bbox(town_files, tmp_path, cache, capsys):
    from aerial_synth.cli import main

    out = tmp_path / "tiled"
    rc = main(["place-tiled", "--scene", str(town_files["pbf"]), "--bbox", _bbox(-200, -200, 200, 200),
               "--scenario", "sparse", "--tile-m", "200", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    data = json.loads((out / "placement.json").read_text())
    assert data["vehicles"] and data["vehicles"][0]["lon_deg"] is not None
