"""The small-vehicle spread (aerial_synth.vehicles.bodies): at least 15 car models over the
market segments, each inside its segment's real size range, with glass, rails and options
that show from above."""

from __future__ import annotations

import numpy as np
import pytest

from aerial_synth.scene.model import MATERIAL_IDS
from aerial_synth.vehicles import build_mesh, load_catalog
from aerial_synth.vehicles.bodies import BODY_SEGMENT, CAR_PROFILES, SEGMENT_SIZES_M
from aerial_synth.vehicles.catalog import OPTION_BODIES
from aerial_synth.vehicles.towed import TOWED_BUILDERS

CAT = load_catalog()
#: the cars: small procedural models but towed bodies (a car-sized utility trailer is a
#: small-vehicle too, vehicles/towed.py, and has no market segment)
SMALL = [m for m in CAT.models if m.cls == "small-vehicle" and m.is_procedural
         and m.body not in TOWED_BUILDERS]


def test_every_small_body_is_a_car_segment_or_towed():
    small = [m for m in CAT.models if m.cls == "small-vehicle" and m.is_procedural]
    assert [m.name for m in small if m.body not in BODY_SEGMENT and m.body not in TOWED_BUILDERS] == []
REQUIRED = ("compact", "sedan", "estate", "hatchback", "suv", "pickup", "van", "minibus")


def test_at_least_15_small_models_over_every_segment():
    in_traffic = [m for m in SMALL if m.weight > 0]
    assert len(in_traffic) >= 15, [m.name for m in in_traffic]
    segments = {BODY_SEGMENT[m.body] for m in in_traffic}
    assert set(REQUIRED) <= segments, set(REQUIRED) - segments
    # the real spread: 3.6 m city cars to 6 m full-size pickups and high-roof minibuses
    lengths = [m.length_m for m in in_traffic]
    assert min(lengths) < 3.7 and max(lengths) > 5.8


@pytest.mark.parametrize("model", SMALL, ids=lambda m: m.name)
def test_size_inside_its_segment_range(model):
    seg = BODY_SEGMENT[model.body]
    for value, (lo, hi), what in zip(model.size_m, SEGMENT_SIZES_M[seg], ("length", "width", "height")):
        assert lo <= value <= hi, f"{model.name} ({seg}) {what} {value} not in [{lo}, {hi}]"


def test_size_ranges_can_refuse():
    """The check above is not vacuous: a bus-sized 'van' or a 2.3 m wide sedan fall outside."""
    (llo, lhi), (wlo, whi), _ = SEGMENT_SIZES_M["van"]
    assert not llo <= 7.0 <= lhi
    assert not SEGMENT_SIZES_M["sedan"][1][0] <= 2.3 <= SEGMENT_SIZES_M["sedan"][1][1]


def _top_down_materials(name: str, step_m: float = 0.02) -> np.ndarray:
    """Material ids of the first surface met by nadir rays over the model's footprint."""
    from aerial_synth.scene.model import Scene
    from aerial_synth.scene.raycast import RayScene

    m = CAT.model(name)
    mesh = build_mesh(m, CAT.color("white"))
    rs = RayScene(Scene(name="t", objects=[]))
    v, f = mesh.to_world(0.0, 0.0, 0.0, 0.0)
    rs.add_vehicle(1, v, f, mesh.face_material, mesh.face_albedo)
    xs, ys = np.meshgrid(np.arange(-m.length_m / 2, m.length_m / 2, step_m),
                         np.arange(-m.width_m / 2, m.width_m / 2, step_m))
    rays = np.zeros((xs.size, 6), np.float32)
    rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = xs.ravel(), ys.ravel(), 10.0, -1.0
    hits = rs.cast_rays(rays)
    return mesh.face_material[hits.face[hits.hit]] if hasattr(hits, "face") else None


@pytest.mark.parametrize("name, lo, hi", [
    ("city_car", 0.15, 0.45), ("hatchback_c", 0.15, 0.45), ("sedan_compact", 0.15, 0.45),
    ("estate", 0.15, 0.45), ("suv_compact", 0.15, 0.45), ("minivan", 0.15, 0.45),
    ("minibus", 0.18, 0.40), ("van_panel", 0.05, 0.18),
])
def test_glass_shows_from_above(name, lo, hi):
    """Windscreen, rear and side windows are a real share of what a nadir camera sees of a
    car (a panel van shows its windscreen only), and all of it is dark."""
    mats = _top_down_materials(name)
    share = float(np.mean(mats == MATERIAL_IDS["glass"]))
    assert lo < share < hi, (name, share)
    mesh = build_mesh(CAT.model(name), CAT.color("white"))
    glass = mesh.face_albedo[mesh.face_material == MATERIAL_IDS["glass"]]
    paint = mesh.face_albedo[mesh.face_material == MATERIAL_IDS["paint"]]
    assert glass.max() < 0.2 and glass.mean() < 0.25 * paint.mean()  # darker than white paint


def test_panel_van_is_painted_where_the_minibus_is_glazed():
    van = build_mesh(CAT.model("van_panel"), CAT.color("white"))
    bus = build_mesh(CAT.model("minibus"), CAT.color("white"))
    gh = van.part_faces("greenhouse")
    assert len(gh) and np.all(van.face_material[gh] == MATERIAL_IDS["paint"])
    assert np.all(bus.face_material[bus.part_faces("greenhouse")] == MATERIAL_IDS["glass"])


def test_rails_and_options():
    for name in ("estate", "minivan", "suv_compact"):
        assert "roof_rails" in build_mesh(CAT.model(name), CAT.color("red")).parts, name
    assert "roof_rails" not in build_mesh(CAT.model("city_car"), CAT.color("red")).parts
    for body, prof in CAR_PROFILES.items():
        for opt in prof.option_rates:
            assert body in OPTION_BODIES[opt]
            assert CAT.options_of(next(m for m in CAT.models if m.body == body))[opt] == prof.option_rates[opt]
    sun = build_mesh(CAT.model("estate+sunroof"), CAT.color("white"))
    assert "sunroof" in sun.parts
