"""Property-based tests (hypothesis) of the scene-spec and label-rules parsers.

Any input (random YAML-able structures, random types in every field) either parses to a
valid Scene / LabelRules or raises an AerialSynthError with a one-line message; never
another exception. Kept fast: small example counts, tiny scenes. Not derandomised: every
run tries new inputs (hypothesis keeps failures in its example database).
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from aerial_synth.errors import AerialSynthError  # noqa: E402
from aerial_synth.scene.label_rules import _RULE_KEYS, _TOP_KEYS, LabelRules, load_rules  # noqa: E402
from aerial_synth.scene.model import LABELS, MATERIALS, Scene  # noqa: E402
from aerial_synth.scene.procedural import generate  # noqa: E402

#: AERIAL_SYNTH_FUZZ_EXAMPLES=2000 explores further (the default keeps the suite fast)
SETTINGS = settings(max_examples=int(os.environ.get("AERIAL_SYNTH_FUZZ_EXAMPLES", "60")),
                    deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# -------------------------------------------------------------------- value strategies
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-1000, 1000),
    st.integers(),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.sampled_from(["abc", "", "1e9", "-5", "nan", "road", "y", "EPSG:32632", "re:(", "*"]),
)
anything = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)


def small(lo, hi):
    return st.floats(lo, hi, allow_nan=False)


def pair_of(lo, hi):
    return st.lists(small(lo, hi), min_size=2, max_size=2)


def maybe(good):
    """Mostly a plausible value, sometimes (about 1 in 8) anything at all."""
    return st.integers(0, 7).flatmap(lambda i: anything if i == 5 else good)


def opt_dict(fields, required=()):
    """A mapping with ``required`` and any subset of the other ``fields`` (each value from its
    strategy), now and then an extra unknown key."""
    keys = [k for k in fields if k not in required]

    @st.composite
    def build(draw):
        chosen = list(required) + draw(st.lists(st.sampled_from(keys), unique=True,
                                                max_size=len(keys)))
        out = {k: draw(fields[k]) for k in chosen}
        if draw(st.integers(0, 19)) == 13:
            out[draw(st.text(min_size=1, max_size=5))] = draw(anything)
        return out

    return build()


road = opt_dict({
    "name": maybe(st.sampled_from(["a", "b", "c"])),
    "points": maybe(st.lists(pair_of(-40, 40), min_size=2, max_size=4)),
    "width_m": maybe(small(0.5, 15)),
    "wiggle_m": maybe(small(0, 3)),
    "sidewalk_m": maybe(small(0, 3)),
    "lanes": maybe(st.integers(0, 3)),
    "centre": maybe(st.sampled_from(["dashed", "solid", "none"])),
    "start_on": maybe(st.sampled_from(["a", "b"])),
    "end_on": maybe(st.sampled_from(["a", "b"])),
    "dead_end": maybe(st.booleans()),
    "oneway": maybe(st.booleans()),
    "smooth": maybe(st.integers(0, 3)),
}, required=("points",))
span_s = maybe(pair_of(0.5, 8).map(sorted))
common = {
    "name": maybe(st.text(min_size=1, max_size=6)),
    "seed": maybe(st.integers(0, 2**32)),
    "size_m": maybe(pair_of(20, 90)),
    "markings": maybe(opt_dict({"enabled": maybe(st.booleans()), "dash_m": maybe(small(0.5, 5)),
                                "gap_m": maybe(small(0.5, 5)),
                                "marking_width_m": maybe(small(0.05, 0.3))})),
    "tree_subdivisions": maybe(st.integers(0, 2)),
}
city_park_spec = opt_dict({
    **common,
    "roads": maybe(st.lists(road, max_size=3)),
    "lakes": maybe(st.lists(opt_dict({"center": maybe(pair_of(-30, 30)),
                                      "radii_m": maybe(pair_of(2, 15)),
                                      "road_clear_m": maybe(small(0, 5))}), max_size=1)),
    "buildings": maybe(opt_dict({"count": maybe(st.integers(0, 4)), "width_m": span_s,
                                 "depth_m": span_s, "height_m": span_s,
                                 "clearance_m": maybe(small(0, 3))})),
    "trees": maybe(opt_dict({"park": maybe(opt_dict({"count": maybe(st.integers(0, 5)),
                                                      "crown_radius_m": span_s,
                                                      "height_m": span_s}))})),
    "poles": maybe(opt_dict({"spacing_m": maybe(small(5, 40)), "height_m": maybe(small(1, 9))})),
}, required=("size_m", "roads")).map(lambda d: {**d, "generator": "city_park"})
suburb_spec = opt_dict({
    **common,
    "grid": maybe(opt_dict({"blocks_x": maybe(st.integers(1, 3)),
                            "blocks_y": maybe(st.integers(1, 3)),
                            "street_width_m": maybe(small(3, 10)),
                            "jitter_m": maybe(small(0, 3)),
                            "cul_de_sac": maybe(opt_dict({"street": maybe(st.integers(0, 2)),
                                                          "from_ew": maybe(st.integers(0, 2)),
                                                          "length_m": maybe(small(5, 30))}))},
                            required=("blocks_x", "blocks_y"))),
    "houses": maybe(opt_dict({"spacing_m": maybe(small(10, 30)),
                              "driveway_prob": maybe(small(0, 1))})),
}, required=("size_m", "grid")).map(lambda d: {**d, "generator": "suburb"})
highway_spec = opt_dict({
    **common,
    "highway": maybe(opt_dict({"lanes": maybe(st.integers(1, 3)),
                               "median_m": maybe(small(1, 10)),
                               "junction_x_m": maybe(st.one_of(small(-20, 20),
                                                               st.lists(small(-20, 20), max_size=2))),
                               "curve_amplitude_m": maybe(small(0, 10))})),
}, required=("highway",)).map(lambda d: {**d, "generator": "highway",
                                          "size_m": d.get("size_m", [200, 120])})
specs = st.integers(0, 9).flatmap(lambda i: [
    anything, st.dictionaries(st.sampled_from(["generator", "seed", "size_m", "roads"]),
                              anything, max_size=4),
    highway_spec, suburb_spec, suburb_spec][i] if i < 5 else city_park_spec)


def _one_line(exc: BaseException) -> str:
    msg = str(exc)
    assert msg and "\n" not in msg, repr(msg)
    return msg


def _check_scene(sc: Scene) -> None:
    assert isinstance(sc, Scene)
    assert any(o.label == "road" and o.n_triangles for o in sc.objects)
    for o in sc.objects:
        assert np.isfinite(o.vertices).all()


@SETTINGS
@given(spec=specs)
def test_spec_parser_never_crashes(spec):
    try:
        sc = generate(spec, source="fuzz.yaml")
    except AerialSynthError as exc:
        _one_line(exc)
        return
    _check_scene(sc)


@SETTINGS
@given(spec=st.one_of(city_park_spec, suburb_spec), seed=st.one_of(st.none(), anything))
def test_spec_file_and_seed_override(spec, seed):
    """Through YAML text and load_scene, with a random seed override."""
    from aerial_synth.scene import load_scene

    try:
        text = yaml.safe_dump(spec)
    except yaml.YAMLError:
        return
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "spec.yaml"
        f.write_text(text)
        try:
            sc = load_scene(f, seed=seed)
        except AerialSynthError as exc:
            assert str(f) in _one_line(exc)
            return
    _check_scene(sc)
    if seed is not None:
        assert sc.meta["seed"] == int(seed) and not isinstance(seed, bool)


# -------------------------------------------------------------------- label rules
rule = opt_dict({
    "match": maybe(st.sampled_from(["road*", "re:^x\\d+$", "Tree*", "*"])),
    "label": maybe(st.sampled_from(LABELS)),
    "material": maybe(st.sampled_from(MATERIALS)),
    "color": maybe(st.lists(small(0, 1), min_size=3, max_size=3)),
})
label_files = st.one_of(
    opt_dict({
        "rules": maybe(st.one_of(st.lists(rule, max_size=3),
                                 st.dictionaries(st.text(min_size=1, max_size=5),
                                                 st.sampled_from(LABELS), max_size=3))),
        "include_defaults": maybe(st.booleans()),
        "units": maybe(st.one_of(st.sampled_from(["m", "cm", "ft"]), small(0.001, 10))),
        "up_axis": maybe(st.sampled_from(["y", "z", "Y"])),
        "default_label": maybe(st.sampled_from(LABELS)),
        "crs": maybe(st.sampled_from(["EPSG:32632", "EPSG:4326", "bogus"])),
        "label_config": maybe(opt_dict({k: maybe(st.lists(st.sampled_from(LABELS), max_size=3))
                                        for k in ("road", "drivable", "obstacles", "ignore")})),
    }),
    anything,
)


@SETTINGS
@given(data=label_files)
def test_label_rules_parser_never_crashes(data):
    assert set(_TOP_KEYS) >= {"rules", "crs"} and "match" in _RULE_KEYS
    try:
        text = yaml.safe_dump(data)
    except yaml.YAMLError:
        return
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "x.labels.yaml"
        f.write_text(text)
        try:
            rules = load_rules(f)
        except AerialSynthError as exc:
            assert str(f) in _one_line(exc)
            return
    assert isinstance(rules, LabelRules)
    assert all(r.label in LABELS for r in rules.rules)
    assert rules.units_m is None or (math.isfinite(rules.units_m) and rules.units_m > 0)
    assert rules.up_axis in (None, "y", "z")
    for r in rules.rules:
        r.matches("Road_1")  # every kept rule can be applied


@SETTINGS
@given(text=st.text(max_size=60))
def test_label_rules_random_text(text):
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "x.labels.yaml"
        f.write_text(text)
        try:
            load_rules(f)
        except AerialSynthError as exc:
            _one_line(exc)
