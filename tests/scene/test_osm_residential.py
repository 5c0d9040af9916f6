"""OSM residential tags: driveway sites from highway=service + service=driveway, house /
garage / shed / pool counts, sheds as hard negatives, driveway parking on them."""

from __future__ import annotations

import numpy as np
import pytest

from .osm_town import Town, rect

pytest.importorskip("osmium")
pytest.importorskip("pyproj")


def _street(tmp_path):
    t = Town()
    t.way([(-150, 0), (0, 0), (150, 0)], {"highway": "residential", "name": "Elm Street"})
    for k, x in enumerate((-90, -30, 30, 90)):
        t.way(rect(x - 6, 16, x + 6, 26), {"building": "detached" if k % 2 else "house"}, close=True)
        t.way(rect(x + 7, 16, x + 12, 22), {"building": "garage"}, close=True)
        t.way([(x + 9.5, 3.25), (x + 9.5, 15.5)], {"highway": "service", "service": "driveway"})
        t.way(rect(x - 4, 34, x - 1, 37), {"building": "shed"}, close=True)
    t.way(rect(-35, 30, -27, 34), {"leisure": "swimming_pool"}, close=True)
    return t.write(tmp_path / "elm.osm")


def test_osm_residential_meta_and_driveway_parking(tmp_path):
    from aerial_synth.placement import place, validate_placement
    from aerial_synth.scene import RayScene
    from aerial_synth.scene.osm import build_osm_scene

    sc = build_osm_scene(_street(tmp_path))
    res = sc.meta["residential"]
    assert res == {"houses": 4, "garages": 4, "sheds": 4, "swimming_pools": 1, "driveways": 4}
    neg = sc.hints.negatives.to_dict()
    assert neg["counts"]["shed"] == 4 and neg["labelled"] is False and len(neg["positions"]) == 4
    hints = sc.hints.driveways
    assert len(hints) == 4
    for h in hints:  # the axis points away from the street (north), the site lies off it
        assert abs(h.axis_deg - 90.0) < 2.5  # (UTM grid convergence)
        assert h.center_xy[1] > 5.0 and h.long_m >= 5.6
    rs = RayScene(sc)
    pl = place(rs, "residential", seed=2, overrides={"lines": 2, "parking": {"kerb_lines": 4}})
    dv = [v for v in pl.vehicles if v.driveway >= 0]
    assert dv and all(v.state == "parked" for v in dv)
    for v in dv:
        h = hints[v.driveway]
        c = np.asarray(h.center_xy)
        assert abs(v.y_m - c[1]) <= h.long_m / 2 and abs(v.x_m - c[0]) <= h.short_m / 2
    rep = validate_placement(rs, pl).summary()
    assert rep["overlaps"] == 0 and rep["footprint_off_drivable"] == 0
