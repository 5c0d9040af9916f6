"""Georeference: placements keep local positions, add original-frame ones and the origin/CRS."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings

import numpy as np
import pytest

from aerial_synth.cli import main
from aerial_synth.placement import Placement, place
from aerial_synth.placement.traffic import PlacementWarning
from aerial_synth.scene.io import export_glb
from aerial_synth.scene.model import Scene
from aerial_synth.scene.raycast import RayScene
from aerial_synth.vehicles import load_catalog

from . import layouts

ORIGIN = (500_000.0, 5_300_000.0, 231.5)  # UTM-like, as photogrammetry and GIS exports are


def _place(scene, seed=3):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlacementWarning)
        return place(RayScene(scene), "jam", seed=seed, catalog=load_catalog(), n_lines=6)


def test_shifted_scene_places_the_same_vehicles_with_original_positions():
    local = layouts.t_junction()
    shifted = dataclasses.replace(local, origin=ORIGIN, crs="EPSG:32632")
    a, b = _place(local), _place(shifted)  # called with a RayScene only: scene from rs.scene
    assert len(a.vehicles) == len(b.vehicles) >= 10
    assert a.georeference == {"origin": [0.0, 0.0, 0.0], "crs": None}
    assert b.georeference == {"origin": list(ORIGIN), "crs": "EPSG:32632"}
    for va, vb in zip(a.vehicles, b.vehicles, strict=True):
        assert (va.x_m, va.y_m, va.z_m, va.heading_rad) == (vb.x_m, vb.y_m, vb.z_m, vb.heading_rad)
        assert (va.x_orig_m, va.y_orig_m, va.z_orig_m) == (va.x_m, va.y_m, va.z_m)
        assert vb.x_orig_m == pytest.approx(vb.x_m + ORIGIN[0], abs=1e-6)
        assert vb.y_orig_m == pytest.approx(vb.y_m + ORIGIN[1], abs=1e-6)
        assert vb.z_orig_m == pytest.approx(vb.z_m + ORIGIN[2], abs=1e-6)
    # UTM zone 32N, 500 km easting: the central meridian, 9 degrees east; ~47.8 degrees north
    lon = np.array([v.lon_deg for v in b.vehicles])
    lat = np.array([v.lat_deg for v in b.vehicles])
    assert np.all(np.abs(lon - 9.0) < 0.01) and np.all(np.abs(lat - 47.84) < 0.02)


def test_placement_json_round_trip_is_exact_with_large_coordinates():
    p = _place(dataclasses.replace(layouts.t_junction(), origin=ORIGIN, crs="EPSG:32632"))
    text = p.to_json()
    back = Placement.from_json(text)
    assert back.to_json() == text
    assert back.georeference == p.georeference
    d = json.loads(text)
    assert d["georeference"] == {"origin": list(ORIGIN), "crs": "EPSG:32632"}
    for v, w in zip(d["vehicles"], back.vehicles, strict=True):
        assert v["x_orig_m"] == w.x_orig_m and v["y_orig_m"] == w.y_orig_m
        assert abs(v["x_orig_m"] - v["x_m"] - ORIGIN[0]) < 2e-6
        assert abs(v["y_orig_m"] - v["y_m"] - ORIGIN[1]) < 2e-6
    # the first vehicle of a line has no spacing: null in JSON, nan after reading, null again
    first = [v for v in back.vehicles if math.isnan(v.spacing_m)]
    assert first and all(json.loads(back.to_json())["vehicles"][v.id - 1]["spacing_m"] is None for v in first)


def test_old_placement_json_without_georeference_still_reads():
    p = _place(layouts.t_junction())
    d = json.loads(p.to_json())
    d.pop("georeference")
    for v in d["vehicles"]:
        for k in ("x_orig_m", "y_orig_m", "z_orig_m", "lon_deg", "lat_deg"):
            v.pop(k, None)
    back = Placement.from_dict(d)
    assert back.georeference is None and math.isnan(back.vehicles[0].x_orig_m)
    assert Placement.from_json(back.to_json()).to_json() == back.to_json()


def test_place_cli_on_a_georeferenced_glb(tmp_path, capsys):
    """The same layout saved once local and once with a UTM origin (glTF node translation):
    the same seed places the same vehicles; original = local + origin within 1 cm, headings
    equal within 0.01 degrees; placement.json records the origin and CRS."""
    scene = layouts.t_junction()
    plain, geo = tmp_path / "plain.glb", tmp_path / "geo.glb"
    export_glb(Scene("tj", scene.objects), plain)
    export_glb(Scene("tj", scene.objects, origin=ORIGIN, crs="EPSG:32632"), geo)
    out = {}
    for name, path in (("plain", plain), ("geo", geo)):
        assert main(["place", "--scene", str(path), "--seed", "5", "--lines", "6", "--no-png",
                     "--out", str(tmp_path / name)]) == 0
        out[name] = json.loads((tmp_path / name / "placement.json").read_text())
    capsys.readouterr()
    assert out["geo"]["georeference"] == {"origin": list(ORIGIN), "crs": "EPSG:32632"}
    va, vb = out["plain"]["vehicles"], out["geo"]["vehicles"]
    assert len(va) == len(vb) >= 10
    for a, b in zip(va, vb, strict=True):
        assert abs(b["x_orig_m"] - ORIGIN[0] - a["x_m"]) < 0.01
        assert abs(b["y_orig_m"] - ORIGIN[1] - a["y_m"]) < 0.01
        dh = math.degrees(abs(math.remainder(a["heading_rad"] - b["heading_rad"], 2 * math.pi)))
        assert dh < 0.01
