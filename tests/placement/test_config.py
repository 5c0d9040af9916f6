"""Scenario configuration: one validation path, errors that name the key, one scenario list."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aerial_synth.errors import AerialSynthError, ConfigError, PlacementError
from aerial_synth.placement import SCENARIOS, ScenarioConfig, load_scenario
from aerial_synth.placement.config import parse_overrides, scenario_dir
from aerial_synth.placement.spacing import SpacingSampler

SPACING_KEYS = "skewness, mean_m, sd_m, min_m, max_m, floor_m"


def _set(*items, scenario="jam"):
    return load_scenario(scenario, parse_overrides(list(items)))


# ----------------------------------------------------------------------------- one list


def test_scenarios_are_the_bundled_files():
    files = sorted(p.stem for p in scenario_dir().glob("*.yaml"))
    assert list(SCENARIOS) == files
    assert {"jam", "normal", "sparse", "random", "multilane"} <= set(SCENARIOS)
    for name in SCENARIOS:
        cfg = load_scenario(name)
        assert cfg.name == name


def test_render_accepts_every_bundled_scenario_and_refuses_others():
    from aerial_synth.cli import build_parser
    from aerial_synth.render.cli import _check_args

    parser = build_parser()
    for name in SCENARIOS:
        _check_args(parser.parse_args(["render", "--scenario", name, "--out", "x"]))
    with pytest.raises(PlacementError, match=r"unknown scenario 'gridlock': expected one of "
                       + ", ".join(SCENARIOS)):
        _check_args(parser.parse_args(["render", "--scenario", "gridlock", "--out", "x"]))


# ------------------------------------------------------------------ --set names the key

SET_CASES = [
    (["spacing.mean_m=abc"], "--set spacing.mean_m: expected a finite number > 0, got 'abc'"),
    (["spacing.mean_m=nan"], "--set spacing.mean_m: expected a finite number > 0, got 'nan'"),
    (["spacing.mean_m=.nan"], "--set spacing.mean_m: expected a finite number > 0, got nan"),
    (["spacing.mean_m=inf"], "--set spacing.mean_m: expected a finite number > 0, got 'inf'"),
    (["spacing.mean_m=.inf"], "--set spacing.mean_m: expected a finite number > 0, got inf"),
    (["spacing.mean_m=-1"], "--set spacing.mean_m: expected a finite number > 0, got -1"),
    (["spacing.mean_m=true"], "--set spacing.mean_m: expected a finite number > 0, got True"),
    (["spacing.bogus_m=1"], f"--set spacing.bogus_m: unknown key; expected one of {SPACING_KEYS}"),
    (["spacing=[1,2]"], "--set spacing: expected a mapping of key: value, got [1, 2]"),
    (["spacing=5"], "--set spacing: expected a mapping of key: value, got 5"),
    (["vehicles_per_line.mean=-3"],
     "--set vehicles_per_line.mean: expected a finite number > 0 and <= 1e+07, got -3"),
    (["vehicles_per_line.min=0"],
     "--set vehicles_per_line.min: expected an integer >= 1 and <= 10000000, got 0"),
    (["vehicles_per_line.sd=.nan"],
     "--set vehicles_per_line.sd: expected a finite number >= 0 and <= 1e+07, got nan"),
    (["gap_m=.nan"], "--set gap_m: expected a finite number >= 0 and <= 10, got nan"),
    (["gap_m=-0.1"], "--set gap_m: expected a finite number >= 0 and <= 10, got -0.1"),
    (["lane_offset_m=0"], "--set lane_offset_m: expected a finite number > 0 and <= 50, got 0"),
    (["lane_offsets_m=[1.75, -2]"],
     "--set lane_offsets_m: expected a list of finite numbers > 0, got [1.75, -2]"),
    (["lane_offsets_m=[]"],
     "--set lane_offsets_m: expected a non-empty list of distances in (0, 50] m or null, got []"),
    (["double_lane_probability=2"],
     "--set double_lane_probability: expected a finite number >= 0 and <= 1, got 2"),
    (["traffic=middle"], "--set traffic: expected one of right, left, got 'middle'"),
    (["kind=parked"], "--set kind: expected one of lines, random, parking, street-parking, mixed, driveways, "
     "got 'parked'"),
    (["lines=0"], "--set lines: expected an integer >= 1 and <= 10000000, got 0"),
    (["vehicles=2.5"], "--set vehicles: expected an integer >= 1 and <= 10000000, got 2.5"),
    (["min_center_distance_m=-8"],
     "--set min_center_distance_m: expected a finite number >= 0 and <= 100, got -8"),
    (["probe.directions=2"], "--set probe.directions: expected an integer >= 4 and <= 360, got 2"),
    (["probe.step_m=0"], "--set probe.step_m: expected a finite number > 0 and <= 1, got 0"),
    (["probe.side_angle_deg=90"],
     "--set probe.side_angle_deg: expected a finite number > 0 and < 90, got 90"),
    (["probe.refine_steps=-1"], "--set probe.refine_steps: expected an integer >= 0 and <= 12, got -1"),
    (["probe=[1]"], "--set probe: expected a mapping of key: value, got [1]"),
    (["seed_batch=0"], "--set seed_batch: expected an integer >= 1 and <= 1000000, got 0"),
    (["spacing.min_m=30"], "--set spacing: d_min (30 m) must not exceed d_max (23.5 m)"),
    (["spacing.mean_m=50"], "--set spacing.mean_m: expected inside (8, 23.5) m, got 50"),
    (["spacing.floor_m=23.5"], "--set spacing: floor/min (23.5 m) leaves no room below d_max (23.5 m)"),
    (["spacing=null"], "--set spacing: a 'lines' scenario needs a spacing block, got null"),
    (["name="], "--set name: expected a non-empty string, got None"),
    (["spacing.sd_m=5", "spacing.min_m=9", "spacing.max_m=12", "spacing.floor_m=null"],
     "--set spacing: no skew-normal law with skewness 30, mean 10.4 m and sd 5 m fits inside [9, 12] m"),
]


@pytest.mark.parametrize("items, message", SET_CASES, ids=[" ".join(c[0]) for c in SET_CASES])
def test_set_errors_name_the_key(items, message):
    with pytest.raises(ConfigError) as exc:
        _set(*items)
    assert str(exc.value) == message


def test_odd_keys_are_quoted_on_one_line(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text('"a\\nb": 1\n')
    with pytest.raises(ConfigError) as exc:
        load_scenario(str(p))
    assert str(exc.value).startswith(f"{p}: 'a\\nb': unknown key; expected one of name, kind, ")
    assert "\n" not in str(exc.value)


def test_unknown_top_level_key_lists_the_valid_ones():
    with pytest.raises(ConfigError) as exc:
        _set("bogus=1")
    msg = str(exc.value)
    assert msg.startswith("--set bogus: unknown key; expected one of name, kind, spacing, ")
    for key in ("gap_m", "lane_offset_m", "double_lane_probability", "probe", "vehicles_per_line"):
        assert key in msg


@pytest.mark.parametrize("item", ["spacing", "=5", ".mean_m=1", "spacing..mean_m=1", "a b=1",
                                  "spacing.mean-m=1", "1x=2"])
def test_malformed_set_items(item):
    with pytest.raises(ConfigError, match=r"^--set .*expected KEY=VALUE"):
        parse_overrides([item])


def test_later_set_wins_and_a_scalar_can_become_a_block():
    assert parse_overrides(["spacing=1", "spacing.mean_m=12"]) == {"spacing": {"mean_m": 12}}
    assert parse_overrides(["spacing.mean_m=12", "spacing.mean_m=13"]) == {"spacing": {"mean_m": 13}}
    assert _set("spacing.mean_m=12", "gap_m=1").spacing.mean_m == 12.0


def test_good_overrides_apply_and_are_converted():
    cfg = _set("spacing.mean_m=12", "vehicles_per_line.mean=5", "gap_m=0", "probe.directions=72.0",
               "lane_offsets_m=[1.75, 5.25]", "traffic=left")
    assert cfg.spacing.mean_m == 12.0 and cfg.vehicles_per_line.mean == 5.0 and cfg.gap_m == 0.0
    assert cfg.probe.directions == 72 and isinstance(cfg.probe.directions, int)
    assert cfg.lane_offsets_m == (1.75, 5.25) and cfg.traffic == "left"


# ---------------------------------------------------------------- errors inside a YAML file


def _yaml_file(tmp_path, mutate, name="my.yaml"):
    data = yaml.safe_load((scenario_dir() / "jam.yaml").read_text())
    mutate(data)
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


@pytest.mark.parametrize(
    "mutate, field, expected",
    [
        (lambda d: d["spacing"].update(mean_m="abc"), "spacing.mean_m", "expected a finite number > 0, got 'abc'"),
        (lambda d: d["spacing"].update(bogus_m=1), "spacing.bogus_m", "unknown key; expected one of"),
        (lambda d: d["spacing"].pop("sd_m"), "spacing.sd_m", "missing; the spacing block needs"),
        (lambda d: d["vehicles_per_line"].update(mean=-3), "vehicles_per_line.mean", "expected a finite number > 0"),
        (lambda d: d.update(gap_m=float("nan")), "gap_m", "expected a finite number >= 0 and <= 10, got nan"),
        (lambda d: d["probe"].update(directions="many"), "probe.directions", "expected an integer >= 4"),
        (lambda d: d.update(lines=-1), "lines", "expected an integer >= 1"),
        (lambda d: d.update(traffic=None), "traffic", "expected one of right, left, got None"),
    ],
)
def test_yaml_errors_name_the_file_and_the_field(tmp_path, mutate, field, expected):
    p = _yaml_file(tmp_path, mutate)
    with pytest.raises(ConfigError) as exc:
        load_scenario(str(p))
    msg = str(exc.value)
    assert msg.startswith(f"{p}: {field}: "), msg
    assert expected in msg
    assert "\n" not in msg


def test_bundled_file_is_named_when_its_values_clash_with_an_override():
    # the override is fine on its own; the file's d_max is what it clashes with
    with pytest.raises(ConfigError) as exc:
        _set("spacing.min_m=30")
    assert "--set spacing" in str(exc.value)
    # an error in a bundled value (no override involved) names scenarios/<name>.yaml
    with pytest.raises(ConfigError) as exc:
        load_scenario("jam", {"spacing": {"mean_m": "x"}}, override_label="override")
    assert str(exc.value) == "override spacing.mean_m: expected a finite number > 0, got 'x'"


@pytest.mark.parametrize(
    "text, expected",
    [
        ("[1, 2]", "expected a mapping at the top level, got list"),
        ("spacing: [", "broken YAML"),
        ("'just a string'", "expected a mapping at the top level, got str"),
        ("{1: 2}", "keys must be names, got 1"),
        ("kind: random\nspacing: null\nvehicles: 0\n", "vehicles: expected an integer >= 1"),
    ],
)
def test_broken_yaml_files(tmp_path, text, expected):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_scenario(str(p))
    assert str(exc.value).startswith(f"{p}: ")
    assert expected in str(exc.value)


def test_missing_file_and_unknown_name():
    with pytest.raises(PlacementError, match="not found"):
        load_scenario("/nonexistent/x.yaml")
    with pytest.raises(PlacementError, match="unknown scenario 'gridlock'"):
        load_scenario("gridlock")


def test_python_built_configs_are_validated_too():
    with pytest.raises(ConfigError, match=r"^gap_m: expected a finite number >= 0"):
        ScenarioConfig(kind="random", gap_m=float("nan"))
    with pytest.raises(ConfigError, match=r"^spacing.mean_m: expected a finite number > 0, got 'abc'"):
        SpacingSampler(skewness=0, mean_m="abc", sd_m=1, min_m=0, max_m=30)
    with pytest.raises(ConfigError, match="lane_offsets_m"):
        ScenarioConfig(kind="random", lane_offsets_m=[float("inf")])


def test_to_dict_round_trip_through_load():
    for name in SCENARIOS:
        cfg = load_scenario(name)
        again = ScenarioConfig.from_mapping(cfg.to_dict(), source="x")
        assert again.to_dict() == cfg.to_dict()


# ------------------------------------------------------------------ property-based tests

_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-10**20, max_value=10**20),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
)
_values = st.recursive(_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)), max_leaves=8)
_KEYS = ["name", "kind", "spacing", "vehicles_per_line", "lane_offset_m", "lane_offsets_m", "traffic",
         "double_lane_probability", "gap_m", "min_center_distance_m", "lines", "vehicles", "probe",
         "seed_batch", "max_seed_attempts", "bogus",
         "spacing.skewness", "spacing.mean_m", "spacing.sd_m", "spacing.min_m", "spacing.max_m",
         "spacing.floor_m", "vehicles_per_line.mean", "vehicles_per_line.sd", "vehicles_per_line.min",
         "probe.step_m", "probe.directions", "probe.max_distance_m", "probe.side_angle_deg",
         "probe.refine_steps", "probe.median_max_m", "probe.max_turn_deg", "probe.edge_jump_m"]
# numbers near the valid ranges make valid configs likely enough to exercise both outcomes
_near = st.one_of(st.floats(min_value=-5, max_value=60), st.integers(min_value=-3, max_value=50),
                  st.sampled_from(["right", "left", "lines", "random", "null", ".nan", "-.inf", "[1, 2]",
                                   "{mean_m: 3}", "abc", "", "~", "1e400", "0x10", "[", "!!binary x"]))


def _assert_valid(cfg: ScenarioConfig) -> None:
    assert isinstance(cfg, ScenarioConfig)
    assert (cfg.kind in ("lines", "random") or cfg.parking is not None) and cfg.traffic in ("right", "left")
    for v in (cfg.lane_offset_m, cfg.gap_m, cfg.double_lane_probability, cfg.probe.step_m):
        assert isinstance(v, float) and math.isfinite(v)
    assert cfg.lane_offset_m > 0 and 0 <= cfg.gap_m <= 10 and 0 <= cfg.double_lane_probability <= 1
    assert cfg.vehicles_per_line.mean > 0 and cfg.vehicles_per_line.min >= 1
    if cfg.kind in ("lines", "mixed"):
        sp = cfg.spacing
        assert 0 < sp.mean_m and sp.lower_m < sp.mean_m < sp.max_m


def _one_line(exc: AerialSynthError) -> None:
    msg = str(exc)
    assert msg and "\n" not in msg and "Traceback" not in msg


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(_KEYS), st.one_of(_near.map(str), st.text(max_size=10))),
                max_size=5),
       st.sampled_from(["jam", "normal", "sparse", "random", "multilane"]))
def test_property_set_parses_or_raises_one_line(pairs, scenario):
    items = [f"{k}={v}" for k, v in pairs]
    try:
        cfg = load_scenario(scenario, parse_overrides(items))
    except AerialSynthError as exc:
        _one_line(exc)
        return
    _assert_valid(cfg)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.text(max_size=20), max_size=4))
def test_property_arbitrary_set_items(items):
    try:
        cfg = load_scenario("jam", parse_overrides(items))
    except AerialSynthError as exc:
        _one_line(exc)
        return
    _assert_valid(cfg)


def _mutated_scenarios():
    base = yaml.safe_load((Path(scenario_dir()) / "jam.yaml").read_text())

    @st.composite
    def build(draw):
        data = yaml.safe_load(yaml.safe_dump(base))
        for _ in range(draw(st.integers(0, 4))):
            key = draw(st.sampled_from(_KEYS))
            value = draw(st.one_of(_values, _near))
            node = data
            parts = key.split(".")
            for p in parts[:-1]:
                if not isinstance(node.get(p), dict):
                    node[p] = {}
                node = node[p]
            if draw(st.booleans()) and parts[-1] in node:
                del node[parts[-1]]
            else:
                node[parts[-1]] = value
        return draw(st.one_of(st.just(data), _values))

    return build()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_mutated_scenarios())
def test_property_scenario_mapping_parses_or_raises_one_line(data):
    try:
        cfg = ScenarioConfig.from_mapping(data, source="s.yaml")
    except AerialSynthError as exc:
        _one_line(exc)
        assert str(exc).startswith("s.yaml: ")
        return
    _assert_valid(cfg)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.text(max_size=200), st.binary(max_size=100).map(lambda b: b.decode("latin-1")),
                 _mutated_scenarios().map(lambda d: yaml.safe_dump(d, allow_unicode=True))))
def test_property_scenario_yaml_text_parses_or_raises_one_line(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("y") / "s.yaml"
    p.write_text(text, encoding="utf-8")
    try:
        cfg = load_scenario(str(p))
    except AerialSynthError as exc:
        _one_line(exc)
        assert str(exc).startswith(f"{p}: ")
        return
    _assert_valid(cfg)
