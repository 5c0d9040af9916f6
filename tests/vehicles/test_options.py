"""Trim options (sunroof, roof rack, roof box, reefer unit, container) and the cowl panel
line: sizes stay within the catalog's length and width, sampling keeps its draws."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
import yaml

from aerial_synth.errors import AssetError
from aerial_synth.vehicles import build_mesh, load_catalog
from aerial_synth.vehicles.catalog import (
    DEFAULT_OPTION_RATES,
    OPTION_BODIES,
    OPTION_RISE_M,
)
from aerial_synth.vehicles.catalog import (
    load_catalog as load,
)

CAT = load_catalog()
RED = CAT.color("red")
PAIRS = [(m.name, o) for m in CAT.models for o, bodies in OPTION_BODIES.items() if m.body in bodies]
OPTION_PARTS = {"sunroof": {"sunroof"}, "roof_rack": {"roof_rack", "ladder"},
                "roof_box": {"roof_box", "roof_rack"}, "reefer": {"reefer"},
                "container": {"container", "container_ribs", "container_corners"}}


def test_every_option_fits_some_bundled_model():
    assert {o for _, o in PAIRS} == set(OPTION_BODIES)


@pytest.mark.parametrize("name,option", PAIRS)
def test_option_mesh_keeps_length_and_width(name, option):
    base = CAT.model(name)
    m = CAT.model(f"{name}+{option}")
    assert m.base_name == name and m.options == (option,) and m.cls == base.cls
    assert (m.length_m, m.width_m) == (base.length_m, base.width_m)
    assert m.height_m == pytest.approx(base.height_m + OPTION_RISE_M[option])
    mesh = build_mesh(m, RED)
    lo, hi = mesh.bounds
    # the label box comes from the mask: nothing may reach past the catalog footprint
    assert hi[0] - lo[0] <= base.length_m + 1e-9 and hi[1] - lo[1] <= base.width_m + 1e-9
    np.testing.assert_allclose(hi - lo, m.size_m, atol=1e-9)
    np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9)
    added = OPTION_PARTS[option] & set(mesh.parts)
    assert added, mesh.parts
    for part in added:
        v, f = mesh.part_mesh(part)
        assert np.all(np.abs(v[:, 0]) <= base.length_m / 2 + 1e-9)
        assert np.all(np.abs(v[:, 1]) <= base.width_m / 2 + 1e-9)
        for piece in trimesh.Trimesh(v, f, process=False).split(only_watertight=False):
            assert piece.is_watertight and piece.volume > 0, (name, option, part)
    # the base body is untouched
    bv, _ = build_mesh(base, RED).part_mesh("body")
    np.testing.assert_array_equal(mesh.part_mesh("body")[0], bv)


@pytest.mark.parametrize("name", ["sedan", "suv", "hatchback", "sport_car"])
def test_sunroof_is_dark_glass_proud_of_the_roof(name):
    mesh = build_mesh(CAT.model(f"{name}+sunroof"), RED)
    sv, _ = mesh.part_mesh("sunroof")
    rv, _ = mesh.part_mesh("roof")
    assert sv[:, 2].max() > rv[:, 2].max() + 0.003  # seen from above, it is the glass
    assert sv[:, 0].min() > rv[:, 0].min() and sv[:, 0].max() < rv[:, 0].max()
    assert np.ptp(sv[:, 1]) < np.ptp(rv[:, 1])
    f = mesh.part_faces("sunroof")
    assert np.all(mesh.face_albedo[f].max(axis=1) < 0.06)


def test_roof_box_and_rack_stand_on_the_roof():
    m = CAT.model("suv+roof_box")
    mesh = build_mesh(m, RED)
    box, _ = mesh.part_mesh("roof_box")
    bars, _ = mesh.part_mesh("roof_rack")
    base_h = CAT.model("suv").height_m
    assert bars[:, 2].min() < base_h < bars[:, 2].max()
    assert box[:, 2].min() >= bars[:, 2].max() - 1e-9 and box[:, 2].max() == pytest.approx(m.height_m)


@pytest.mark.parametrize("name", ["sedan", "hatchback", "box_truck", "pickup_truck"])
def test_cowl_strip_lies_on_the_bonnet_in_front_of_the_windscreen(name):
    mesh = build_mesh(CAT.model(name), RED)
    cv, _ = mesh.part_mesh("cowl")
    ws, _ = mesh.part_mesh("windscreen")
    bv, _ = mesh.part_mesh("body")
    assert cv[:, 0].min() >= ws[:, 0].max() - 0.1  # just ahead of the glass's lower edge
    assert cv[:, 0].max() < bv[:, 0].max()
    assert np.ptp(cv[:, 0]) < 0.1 and np.ptp(cv[:, 1]) > 1.0
    f = mesh.part_faces("cowl")
    assert np.all(mesh.face_albedo[f] < 0.05)


# ------------------------------------------------------------------------------ sampling
def test_sampling_keeps_models_colours_and_later_draws():
    n = 500
    a = np.random.default_rng(99)
    draws = CAT.sample(a, n)
    after = a.random(4)
    b = np.random.default_rng(99)
    mi = b.choice(len(CAT.models), size=n, p=CAT.model_probabilities)
    ci = b.choice(len(CAT.colors), size=n, p=CAT.color_probabilities)
    assert [v.model.base_name for v in draws] == [CAT.models[i].name for i in mi]
    assert [v.color.name for v in draws] == [CAT.colors[j].name for j in ci]
    np.testing.assert_array_equal(after, b.random(4))  # the caller's stream is unchanged
    assert any(v.model.options for v in draws)
    again = CAT.sample(np.random.default_rng(99), n)
    assert [v.name for v in again] == [v.name for v in draws]
    # a second call from the advanced generator draws other options
    c = np.random.default_rng(99)
    first, second = CAT.sample(c, n), CAT.sample(c, n)
    assert [v.model.options for v in first] != [v.model.options for v in second]


def test_option_shares_follow_the_rates():
    draws = CAT.sample(np.random.default_rng(2024), 40_000)
    for base in ("sedan", "suv"):
        sel = [v for v in draws if v.model.base_name == base]
        for opt, p in DEFAULT_OPTION_RATES[base].items():
            k = sum(v.model.options == (opt,) for v in sel)
            sd = np.sqrt(len(sel) * p * (1 - p))
            assert abs(k - len(sel) * p) < 4.5 * sd, (base, opt, k, len(sel), p)


def test_option_names_resolve_and_refuse_bad_ones():
    assert CAT.model("sedan+sunroof") is CAT.model("sedan+sunroof")
    with pytest.raises(AssetError, match="option 'container' does not fit"):
        CAT.model("sedan+container")
    with pytest.raises(AssetError, match="unknown option 'wings'"):
        CAT.model("sedan+wings")
    with pytest.raises(AssetError, match="unknown vehicle model 'tank\\+sunroof'"):
        CAT.model("tank+sunroof")


def _catalog(tmp_path, **model_extra):
    data = {"version": 1, "colors": [{"name": "white", "rgb": [0.8, 0.8, 0.8]}],
            "models": [{"name": "car", "body": "sedan", "class": "small-vehicle",
                        "length_m": 4.6, "width_m": 1.8, "height_m": 1.45, **model_extra}]}
    p = tmp_path / "catalog.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


def test_catalog_options_field(tmp_path):
    cat = load(_catalog(tmp_path, options={"roof_box": 1.0}))
    assert all(v.model.name == "car+roof_box" for v in cat.sample(np.random.default_rng(0), 20))
    cat = load(_catalog(tmp_path, options={}))
    assert not any(v.model.options for v in cat.sample(np.random.default_rng(0), 200))
    for opts, msg in (({"reefer": 0.1}, "option 'reefer' does not fit body 'sedan'"),
                      ({"sunroof": 1.5}, r"options.sunroof: expected a probability in \[0, 1\]"),
                      ({"sunroof": 0.6, "roof_box": 0.6}, "sum to at most 1"),
                      ([1], "expected a mapping of option: probability")):
        with pytest.raises(AssetError, match=msg):
            load(_catalog(tmp_path, options=opts))
    with pytest.raises(AssetError, match="without '\\+'"):
        load(_catalog(tmp_path, name="a+b"))


@pytest.mark.parametrize("name", ["city_bus", "coach", "school_bus"])
def test_buses_carry_roof_units_and_vents_on_the_roof(name):
    m = CAT.model(name)
    mesh = build_mesh(m, RED)
    roof, _ = mesh.part_mesh("roof")
    for part in ("air_conditioner", "roof_vents"):
        v, _ = mesh.part_mesh(part)
        assert len(v), part
        assert v[:, 2].max() > roof[:, 2].max() and v[:, 2].max() <= m.height_m + 1e-9
        assert np.all(np.abs(v[:, 0]) < m.length_m / 2) and np.all(np.abs(v[:, 1]) < m.width_m / 2)
    vx, _ = mesh.part_mesh("roof_vents")
    assert np.ptp(vx[:, 0]) > 0.5 * m.length_m  # near both ends
