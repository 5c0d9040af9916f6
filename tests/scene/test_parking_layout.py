"""Parking lot layouts: bays, painted lines, entrances, the depot scene, spec validation."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from aerial_synth.errors import SceneError
from aerial_synth.scene import RayScene, load_scene
from aerial_synth.scene.model import LABEL_IDS, LABELS, LabelConfig
from aerial_synth.scene.parking_layout import (
    LotLayout,
    bay_markings,
    layout_bays,
    lot_frame,
    parse_layout,
)
from aerial_synth.scene.procedural import generate


def _bays(w=60.0, h=40.0, rot=0.0, **lay):
    poly = shapely.affinity.rotate(shapely.box(-w / 2, -h / 2, w / 2, h / 2), rot, origin=(0, 0))
    fr = lot_frame(poly)
    layout = LotLayout(**lay)
    return poly, fr, layout, layout_bays(fr, layout)


def test_parking_marking_is_the_last_label_and_drivable():
    assert LABELS[-1] == "parking_marking"
    assert LABEL_IDS["vehicle"] == 11  # earlier semantic ids keep their values
    assert "parking_marking" in LabelConfig().drivable
    assert "parking_marking" not in LabelConfig().road


@pytest.mark.parametrize("angle", [90.0, 60.0, 45.0, 0.0])
@pytest.mark.parametrize("rot", [0.0, 33.0])
def test_bays_lie_inside_the_lot_and_never_overlap(angle, rot):
    poly, fr, lay, bays = _bays(rot=rot, angle_deg=angle)
    assert len(bays) > 10
    rects = shapely.polygons(bays.corners())
    assert shapely.contains(poly.buffer(1e-6), rects).all()
    tree = shapely.STRtree(rects)
    a, b = tree.query(rects, predicate="intersects")
    keep = a < b
    inter = shapely.area(shapely.intersection(rects[a[keep]], rects[b[keep]]))
    assert (inter < 1e-6).all()
    np.testing.assert_allclose(shapely.area(rects), lay.bay_width_m * lay.bay_length_m)
    # bay axis at the bay angle to the row direction (rows along the long side)
    rel = np.degrees(np.angle(np.exp(1j * (bays.axis_rad - fr.u_rad))))
    off = np.minimum(np.abs(rel), 180 - np.abs(rel))
    np.testing.assert_allclose(off, min(angle, 180 - angle), atol=1e-9)
    assert abs(np.degrees(fr.u_rad) % 180 - rot % 180) < 1e-6


def test_every_bay_opens_onto_an_aisle():
    """A car leaving a bay backwards (nose-in) reaches free asphalt: the strip of aisle depth
    behind every bay is clear of bays."""
    poly, fr, lay, bays = _bays(w=70, h=50)
    rects = shapely.polygons(bays.corners())
    back = -np.stack([np.cos(bays.axis_rad), np.sin(bays.axis_rad)], 1)
    c = bays.centre_xy + back * (lay.bay_length_m / 2 + lay.aisle_m / 2)
    probe = shapely.buffer(shapely.points(c), 0.5)
    assert not shapely.intersects(shapely.union_all(rects), probe).any()
    assert shapely.contains(poly, probe).all()


def test_perpendicular_lot_counts_and_rows():
    # 55 x 50 m, 2.5 x 5 bays, 6 m aisles: 6 rows of 17 (ends keep a 6 m circulation lane)
    _, fr, lay, bays = _bays(w=55, h=50)
    assert len(bays) == 102
    assert len(np.unique(bays.row)) == 6
    assert np.bincount(bays.row).tolist() == [17] * 6


def test_rows_limit_and_markings():
    _, _, lay, bays = _bays(w=60, h=40, rows=2)
    assert len(np.unique(bays.row)) == 2
    m = bay_markings(bays, lay)
    # two lines per bay (shared lines merge), each line_width x bay_length
    n_lines = len(bays) + 2 * 1  # per row: n + 1 separators, two rows
    assert m.area == pytest.approx(n_lines * lay.line_width_m * lay.bay_length_m, rel=0.02)


@pytest.mark.parametrize("bad, field", [
    ({"angle_deg": 30}, "angle_deg"),
    ({"bay_width_m": -1}, "bay_width_m"),
    ({"aisle_m": "wide"}, "aisle_m"),
    ({"colour": 1}, "colour"),
])
def test_bad_layout_is_one_line(bad, field):
    with pytest.raises(SceneError) as e:
        parse_layout(bad, "parking_lots[0].layout")
    msg = str(e.value)
    assert "\n" not in msg and "parking_lots[0].layout" in msg and field in msg


def test_bay_larger_than_its_lot_is_refused():
    spec = {"name": "t", "generator": "depot", "seed": 1, "size_m": [240, 200],
            "yards": [{"center": [-62, -26], "size_m": [30, 20], "layout": {"bay_length_m": 18.0,
                                                                         "aisle_m": 20.0}}]}
    with pytest.raises(SceneError) as e:
        generate(spec, source="t.yaml")
    msg = str(e.value)
    assert "\n" not in msg and "yards[0].layout" in msg and "needs a lot of at least" in msg


@pytest.fixture(scope="module")
def suburb():
    return load_scene("suburb")


def test_suburb_lots_are_joined_to_the_street_network(suburb):
    """The drivable surface (road + parking + markings) around each lot is one piece with
    the street grid: the lots' entrances fixed the split network."""
    t = suburb.truth
    lots = [shapely.box(92.5, 95, 147.5, 145), shapely.box(-145, -222.5, -95, -177.5)]
    drivable = shapely.union_all([t.road_area.buffer(0.01), t.parking_area.buffer(0.01)])
    parts = list(shapely.get_parts(drivable))
    road_part = max(parts, key=lambda p: p.intersection(t.road_area).area)
    for lot in lots:
        assert road_part.contains(lot.buffer(-0.5))


def test_suburb_lots_show_painted_bays(suburb):
    rs = RayScene(suburb)
    hints = suburb.hints.lots
    assert [h.bays for h in hints] == [102, 75]
    xs, ys = np.meshgrid(np.arange(95, 145, 0.05), [100.0, 115.0])
    lab = rs.trace_labels(np.stack([xs.ravel(), ys.ravel()], 1)).reshape(xs.shape)
    marks = lab == LABEL_IDS["parking_marking"]
    # one line every 2.5 m along a row of bays, none along the aisle (y = 115 lies in one)
    runs = np.flatnonzero(np.diff(marks[0].astype(int)) == 1)
    assert len(runs) == 18
    np.testing.assert_allclose(np.diff(xs[0][runs + 1]), 2.5, atol=0.06)


def test_depot_has_long_bays_and_entrances():
    s = load_scene("depot")
    hints = s.hints.lots
    assert [h.layout_dict()["bay_length_m"] for h in hints] == [14.0, 18.0]
    assert all(h.bays >= 40 for h in hints)
    t = s.truth
    drivable = shapely.union_all([t.road_area.buffer(0.01), t.parking_area.buffer(0.01)])
    assert len(list(shapely.get_parts(drivable))) == 1  # yards joined to the road
