"""Typed scene hints (scene/scene_hints.py): validation at construction, and no Scene.meta
string key for hints crossing packages."""

import re
from pathlib import Path

import numpy as np
import pytest

from aerial_synth.errors import SceneError
from aerial_synth.scene.scene_hints import (
    NO_HINTS,
    DrivewayHint,
    KerbHint,
    LotHint,
    NegativesHint,
    SceneHints,
)

PKG = Path(__file__).resolve().parents[2] / "aerial_synth"
DRIVE = {"id": 3, "kind": "pad", "center_xy": [1.5, -2.0], "axis_deg": 30.0, "long_m": 6.0,
         "short_m": 3.0, "bay_m": [6.0, 3.0], "occupancy": 0.5, "mix": {"small-vehicle": 2}}


def test_driveway_hint_from_dict_keeps_every_field():
    h = DrivewayHint.from_dict(DRIVE)
    assert (h.id, h.kind, h.center_xy, h.bay_m, h.occupancy) == (3, "pad", (1.5, -2.0), (6.0, 3.0), 0.5)
    assert h.mix_dict() == {"small-vehicle": 2} and h.labels is None
    assert DrivewayHint.from_dict({**DRIVE, "mix": {}}).mix_dict() == {"small-vehicle": 1.0}


@pytest.mark.parametrize("field, value, expected", [
    ("kind", "garage", "driveway, pad or yard"),
    ("center_xy", [1.0], "an [x, y] pair"),
    ("long_m", "six", "a finite number"),
    ("occupancy", 1.5, "a fraction in [0, 1]"),
    ("mix", {"small-vehicle": "lots"}, "a finite number"),
])
def test_driveway_hint_names_the_bad_field(field, value, expected):
    with pytest.raises(SceneError) as e:
        DrivewayHint.from_dict({**DRIVE, field: value}, "scene x: driveway hint")
    msg = str(e.value)
    assert msg.startswith("scene x: driveway hint") and field in msg and expected in msg
    assert repr(value["small-vehicle"] if field == "mix" else value) in msg


def test_missing_field_is_named():
    d = dict(DRIVE)
    del d["axis_deg"]
    with pytest.raises(SceneError, match="scene y: field 'axis_deg'"):
        DrivewayHint.from_dict(d, "scene y")


def test_negatives_round_trip_and_never_labelled():
    d = {"scene_kind": "rural", "density_per_ha": {"shed": 1.5, "boat": 0.0}, "counts": {"shed": 2, "boat": 0},
         "labelled": False, "positions": [["shed", 1.0, 2.0], ["shed", 3.0, 4.0]]}
    assert NegativesHint.from_dict(d).to_dict() == d
    assert list(NegativesHint.from_dict(d).to_dict()) == list(d)
    with pytest.raises(SceneError, match="labelled"):
        NegativesHint.from_dict({**d, "labelled": True})


def test_lot_kerb_and_scene_hints_check_types():
    lot = LotHint.from_dict({"id": 0, "center_xy": [0, 0], "row_deg": 90, "long_m": 40, "short_m": 20,
                             "layout": {"bay_length_m": 5.0}, "bays": 10})
    assert lot.layout_dict() == {"bay_length_m": 5.0} and lot.row_deg == 90.0
    with pytest.raises(SceneError, match="coords"):
        KerbHint(coords=[[0.0, 0.0]])
    k = KerbHint.from_dict({"coords": [[0, 0], [10, 0]], "left": True})
    assert k.coords.shape == (2, 2) and (k.left, k.right, k.width_m) == (True, None, 6.0)
    with pytest.raises(SceneError, match=r"driveways\[0\]"):
        SceneHints(driveways=(lot,))
    with pytest.raises(SceneError, match=r"spaces\[0\]"):
        SceneHints(spaces=(np.zeros((2, 2)),))
    assert not NO_HINTS and SceneHints(lots=(lot,))
    assert NO_HINTS.replace(lots=(lot,)).lots == (lot,)


def test_no_hint_travels_in_scene_meta():
    """No module reads or writes a hint under a Scene.meta string key any more."""
    keys = "driveways|parking_lots|parking_spaces|kerb_parking|hard_negatives|road_hints"
    pat = re.compile(rf"""meta(\.get\(|\[)\s*["']({keys})["']|["']({keys})["']\s*:\s*(r\[|hints\b|kerbs\b|neg)""")
    bad = [f"{p.relative_to(PKG)}:{i}" for p in PKG.rglob("*.py")
           for i, line in enumerate(p.read_text().splitlines(), 1) if pat.search(line)]
    assert bad == []
