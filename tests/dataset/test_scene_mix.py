"""``export --scene-mix``: parsing, name checks, weights over many draws, and a mixed export
whose every image records the scene and scenario its placement group drew."""

import json

import numpy as np
import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.dataset.scene_mix import PRESETS, MixEntry, SceneMix, check_names, parse_mix
from aerial_synth.errors import ExportError
from aerial_synth.formats import meta
from aerial_synth.render.config import RenderOptions

from ..helpers import write_crossing_obj
from .conftest import run_cli


def test_text_form_and_canonical_text():
    m = parse_mix("city_park/jam:2, highway/normal:1,depot:0.5")
    assert m.entries == (MixEntry("city_park", "jam", 2.0), MixEntry("highway", "normal", 1.0),
                         MixEntry("depot", None, 0.5))
    assert m.text() == "city_park/jam:2,highway/normal:1,depot:0.5"
    assert parse_mix(m.text()) == m
    assert np.allclose(m.probabilities, [2 / 3.5, 1 / 3.5, 0.5 / 3.5])


def test_yaml_forms(tmp_path):
    a = tmp_path / "a.yaml"
    a.write_text("- {scene: city_park, scenario: jam, weight: 3}\n- {scene: suburb}\n")
    b = tmp_path / "b.yaml"
    b.write_text("entries:\n  - {scene: city_park, scenario: jam, weight: 3}\n  - {scene: suburb, weight: 1}\n")
    assert parse_mix(a) == parse_mix(str(b)) == parse_mix("city_park/jam:3,suburb:1")


@pytest.mark.parametrize("spec, says", [
    ("city_park:0", "expected a weight > 0, got '0'"),
    ("city_park:-1", "expected a weight > 0"),
    ("city_park:x", "expected a weight > 0, got 'x'"),
    ("city_park:nan", "expected a weight > 0"),
    ("city_park:1,:2", "entry 2: expected SCENE[/SCENARIO]:WEIGHT"),
    ("", "expected NAME[/SCENARIO]:WEIGHT"),
    ("missing.yaml", "file not found"),
])
def test_bad_text_is_one_line(spec, says):
    with pytest.raises(ExportError) as e:
        parse_mix(spec)
    assert says in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("body, says", [
    ("[]", "expected a non-empty list"),
    ("- {scene: city_park, speed: 3}", "entries[0]: unknown key(s) speed"),
    ("- city_park", "entries[0]: expected a mapping"),
    ("- {scene: city_park, weight: 0}", "entries[0]: expected a weight > 0"),
    ("nope: 1", "unknown key(s) nope"),
    ("- [unclosed", "broken YAML (line 1"),
])
def test_bad_yaml_names_the_entry(tmp_path, body, says):
    p = tmp_path / "mix.yaml"
    p.write_text(body)
    with pytest.raises(ExportError) as e:
        parse_mix(p)
    assert says in str(e.value) and "\n" not in str(e.value)


def test_unknown_names_are_refused():
    with pytest.raises(ExportError, match=r"entry 2: unknown scene 'moon_base'; expected one of .*city_park"):
        check_names(parse_mix("city_park/jam:1,moon_base:2"), "jam")
    with pytest.raises(ExportError, match=r"entry 1 \(city_park/nojam:1\): unknown scenario 'nojam'"):
        check_names(parse_mix("city_park/nojam:1"), "jam")
    with pytest.raises(ExportError, match="scene file 'no/such.obj' not found"):
        check_names(parse_mix("no/such.obj:1"), "jam")
    check_names(parse_mix("default"), "jam")  # every preset names what exists
    for name in PRESETS:
        check_names(parse_mix(name), "jam")


def test_weights_are_honoured_over_many_draws():
    m = SceneMix((MixEntry("a", None, 1.0), MixEntry("b", None, 3.0), MixEntry("c", None, 0.5),
                  MixEntry("d", None, 5.5)))
    n = 20000
    k = np.bincount([m.index_for_group(11, g) for g in range(n)], minlength=4)
    p = m.probabilities
    # each share within 4 binomial standard deviations (a wrong weight is off by 10+)
    assert np.all(np.abs(k / n - p) < 4 * np.sqrt(p * (1 - p) / n)), (k / n, p)
    from scipy.stats import chisquare

    assert chisquare(k, n * p).pvalue > 1e-4
    # deterministic per (seed, group), and another seed draws another sequence
    assert [m.index_for_group(11, g) for g in range(50)] == [m.index_for_group(11, g) for g in range(50)]
    assert [m.index_for_group(12, g) for g in range(50)] != [m.index_for_group(11, g) for g in range(50)]


def test_cli_unknown_scene_in_mix_one_line_exit_2(tmp_path):
    out = tmp_path / "ds"
    p = run_cli("export", "--out", out, "--images", 1, "--scene-mix", "city_park/jam:1,moon_base:1")
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "--scene-mix entry 2: unknown scene 'moon_base'" in lines[0]
    assert "Traceback" not in p.stderr and not out.exists()


def test_mix_refused_with_tiles():
    with pytest.raises(ExportError, match="--scene-mix: not with --tile-m"):
        ExportConfig(scene_mix="city_park:1", tile_m=200.0)


def test_mixed_export_records_each_groups_scene_and_scenario(tmp_path):
    a = write_crossing_obj(tmp_path / "a.obj", 40)
    b = write_crossing_obj(tmp_path / "b.obj", 50)
    mix = f"{a}/jam:1,{b}/normal:1"
    cfg = ExportConfig(scene_mix=mix, images=6, formats="dota", split=0.5, seed=5,
                       images_per_placement=1, n_vehicles=6,
                       camera=CameraConfig(width_px=96, height_px=96),
                       render=RenderOptions(preset="fast"),
                       simple_vehicles=True)
    out = tmp_path / "ds"
    export_dataset(cfg, out, workers=1, progress=False)
    m = parse_mix(cfg.scene_mix)
    man = json.loads((out / "manifest.json").read_text())
    assert man["parameters"]["scene_mix"] == m.text()
    seen = set()
    for i in range(6):
        rec = meta.read(out / "meta" / f"{i:06d}.json")
        k = m.index_for_group(5, i)
        want = {"entry": k, "scene": m.entries[k].scene, "scenario": m.entries[k].scenario}
        assert rec.placement["scene_mix"] == want
        assert rec.placement["scenario"] == want["scenario"]
        assert rec.placement["scene"] == ("a" if k == 0 else "b")
        seen.add(k)
    assert seen == {0, 1}  # both entries drawn by these six groups (seed 5)


@pytest.mark.slow  # loads four bundled scenes and places ~2000 vehicles (~30 s)
def test_every_default_entry_places_vehicles():
    from aerial_synth.placement import place
    from aerial_synth.scene import load_scene
    from aerial_synth.scene.raycast import RayScene
    from aerial_synth.vehicles import load_catalog

    cat = load_catalog()
    scenes = {}
    for e in parse_mix("default").entries:
        s = scenes.setdefault(e.scene, load_scene(e.scene))
        pl = place(RayScene(s), e.scenario, np.random.default_rng(0), catalog=cat, scene_name=e.scene)
        assert len(pl.vehicles) > 20, e


@pytest.mark.parametrize("path", ["/dev/null", "FOLDER"])
def test_a_path_that_is_not_a_yaml_file_is_named_as_such(path, tmp_path):
    """`--scene-mix /dev/null` used to read as an entry: scene '/dev', scenario 'null'."""
    path = str(tmp_path) if path == "FOLDER" else path
    with pytest.raises(ExportError, match=rf"--scene-mix {path}: expected a YAML file, found"):
        parse_mix(path)
