"""Property-based tests of the catalog parser: any input parses or fails with one line."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aerial_synth.errors import AerialSynthError, AssetError
from aerial_synth.vehicles.catalog import CATALOG_VERSION, catalog_from_mapping, load_catalog

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-10, 10**20), st.text(max_size=6),
    st.floats(allow_nan=True, allow_infinity=True),
)
values = st.recursive(scalars, lambda c: st.lists(c, max_size=3) | st.dictionaries(
    st.text(max_size=5), c, max_size=3), max_leaves=6)

COLOR_KEYS = ["name", "rgb", "weight", "bogus"]
MODEL_KEYS = ["name", "pack", "body", "class", "length_m", "width_m", "height_m", "weight",
              "mesh", "scale", "forward", "up"]


def _entry(keys):
    return st.dictionaries(st.sampled_from(keys), values | st.sampled_from(
        ["small-vehicle", "hatchback", "+x", "-z", 4.2, 1.8, [0.5, 0.5, 0.5], "x"]), max_size=8)


catalogs = st.one_of(
    values,
    st.fixed_dictionaries(
        {"colors": st.lists(_entry(COLOR_KEYS), max_size=3) | values,
         "models": st.lists(_entry(MODEL_KEYS), max_size=3) | values},
        optional={"version": values | st.just(1), "extra": values},
    ),
)


def _valid():
    return {
        "version": 1,
        "colors": [{"name": "white", "rgb": [0.9, 0.9, 0.9], "weight": 1}],
        "models": [{"name": "car", "pack": 1, "body": "hatchback", "class": "small-vehicle",
                    "length_m": 4.2, "width_m": 1.8, "height_m": 1.5}],
    }


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(catalogs)
def test_any_mapping_parses_or_fails_in_one_line(data):
    try:
        cat = catalog_from_mapping(data)
    except AerialSynthError as exc:
        assert "\n" not in str(exc) and str(exc)
        return
    assert cat.models and cat.colors
    assert all(m.length_m > 0 and m.width_m > 0 for m in cat.models)


@settings(max_examples=150, deadline=None)
@given(field=st.sampled_from(["length_m", "width_m", "height_m", "weight"]), value=values)
def test_one_bad_field_is_named(field, value):
    data = _valid()
    data["models"][0][field] = value
    try:
        catalog_from_mapping(data)
    except AssetError as exc:
        assert field.split("_")[0] in str(exc) and "\n" not in str(exc)


@pytest.mark.parametrize("version", [2, 0, "1", True, None, 1.5])
def test_unknown_catalog_version_is_refused(tmp_path, version):
    data = _valid()
    data["version"] = version
    p = tmp_path / "catalog.yaml"
    p.write_text(yaml.safe_dump(data))
    with pytest.raises(AssetError, match=r"version: expected 1 .*got"):
        load_catalog(p)


def test_current_version_and_no_version_load():
    data = _valid()
    assert catalog_from_mapping(data).models[0].name == "car"
    del data["version"]
    assert catalog_from_mapping(data).models[0].name == "car"
    assert CATALOG_VERSION == 1
