"""``export --gsd LO:HI`` / ``--altitude LO:HI``: per-image GSD, its draw, its records, and box
sizes in metres that do not depend on the GSD (aerial_synth.dataset.gsd)."""

import json
import math

import numpy as np
import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.dataset.gsd import GsdRange, image_camera_config, image_gsd_m, parse_range
from aerial_synth.errors import ExportError
from aerial_synth.evaluate.stats import dataset_stats
from aerial_synth.formats import dota, meta
from aerial_synth.render.config import RenderOptions

from .conftest import run_cli, tree_bytes


@pytest.mark.parametrize("text, want", [
    ("0.12", 0.12), ("0.05:0.3", (0.05, 0.3)), (" 1:2 ", (1.0, 2.0)), ([0.05, 0.3], (0.05, 0.3)),
    (0.2, 0.2),
])
def test_parse_range_accepts(text, want):
    assert parse_range("--gsd", text) == want


@pytest.mark.parametrize("text, says", [
    ("0.3:0.05", "LO < HI"), ("0.1:0.1", "LO < HI"), ("a:b", "range LO:HI of numbers"),
    ("0:1", "values > 0"), ("-1:2", "values > 0"), ("nan:1", "values > 0"), ("1:inf", "values > 0"),
    ("1:2:3", "a number > 0 or a range"), ("", "range LO:HI of numbers"), (True, "a number > 0"),
    (None, "a number > 0"),
])
def test_parse_range_refuses_with_one_line(text, says):
    with pytest.raises(ExportError) as e:
        parse_range("--gsd", text)
    msg = str(e.value)
    assert msg.startswith("--gsd: ") and says in msg and "\n" not in msg


def test_draws_are_log_uniform_within_the_range():
    r = GsdRange(focal_px=490.0, gsd_lo_m=0.05, gsd_hi_m=0.3)
    rng = np.random.default_rng(1)
    g = np.array([r.draw(rng) for _ in range(8000)])
    assert g.min() >= 0.05 and g.max() <= 0.3
    # log-uniform: half below the geometric mean, equal shares per octave
    assert np.mean(g < math.sqrt(0.05 * 0.3)) == pytest.approx(0.5, abs=0.02)
    share_first_octave = np.mean(g < 0.1)  # log(2) / log(6) = 0.387
    assert share_first_octave == pytest.approx(math.log(2) / math.log(6), abs=0.02)
    # a uniform draw would put only 20 % there: the test can tell the two apart
    u = GsdRange(490.0, 0.05, 0.3, "uniform")
    gu = np.array([u.draw(rng) for _ in range(8000)])
    assert np.mean(gu < 0.1) == pytest.approx(0.2, abs=0.02)


def test_range_keeps_the_lens_and_moves_the_camera():
    cfg = ExportConfig(gsd_range=(0.05, 0.3), seed=4)
    r = GsdRange.of(cfg)
    assert r.focal_px == pytest.approx(60.0 / math.sqrt(0.05 * 0.3))
    for i in range(20):
        g = image_gsd_m(cfg, i)
        cc = image_camera_config(cfg, i)
        assert 0.05 <= g <= 0.3
        assert cc.f_px == pytest.approx(r.focal_px) and cc.nadir_gsd_m == pytest.approx(g)
        assert image_gsd_m(cfg, i) == g  # deterministic per (seed, index)
    assert cfg.camera_config().nadir_gsd_m == pytest.approx(0.3)  # the widest, for pads
    # --altitude LO:HI: the lens from the default GSD at the range's geometric centre
    cfg = ExportConfig(altitude_range=(30.0, 120.0))
    r = GsdRange.of(cfg)
    assert r.focal_px == pytest.approx(60.0 / 0.12)
    assert (r.gsd_lo_m, r.gsd_hi_m) == pytest.approx((0.06, 0.24))
    # no range: the plain camera, byte-identical exports as before
    cfg = ExportConfig(camera=CameraConfig(gsd_m=0.1))
    assert GsdRange.of(cfg) is None and image_gsd_m(cfg, 0) is None
    assert image_camera_config(cfg, 3) == cfg.camera_config()


def test_config_refuses_conflicts_and_round_trips():
    with pytest.raises(ExportError, match="give a range to one of them"):
        ExportConfig(gsd_range=(0.05, 0.3), altitude_range=(30, 90))
    with pytest.raises(ExportError, match="one value or one range"):
        ExportConfig(gsd_range=(0.05, 0.3), camera=CameraConfig(gsd_m=0.1))
    with pytest.raises(ExportError, match="LO < HI"):
        ExportConfig(gsd_range=(0.3, 0.05))
    cfg = ExportConfig(gsd_range=[0.05, 0.3])
    d = cfg.to_dict()
    assert d["gsd_range"] == [0.05, 0.3] and "altitude_range" not in d
    assert ExportConfig.from_dict(json.loads(json.dumps(d))) == cfg
    assert "gsd_range" not in ExportConfig().to_dict()  # old manifests keep their bytes


@pytest.mark.parametrize("args, says", [
    (["--gsd", "0.3:0.05"], "--gsd: expected a range LO:HI with LO < HI, got '0.3:0.05'"),
    (["--gsd", "a:b"], "--gsd: expected a number > 0 or a range LO:HI of numbers, got 'a:b'"),
    (["--gsd", "0:1"], "--gsd: expected values > 0 (metres), got '0:1'"),
    (["--altitude", "90:30"], "--altitude: expected a range LO:HI with LO < HI"),
    (["--gsd", "0.05:0.3", "--altitude", "30:90"], "give a range to one of them"),
])
def test_cli_bad_ranges_one_line_exit_2(tmp_path, args, says):
    out = tmp_path / "ds"
    p = run_cli("export", "--out", out, "--images", 1, *args)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "Traceback" not in p.stderr
    assert not out.exists()


def _ranged(scene, **kw):
    base = dict(scene=scene, images=6, formats="dota,eagle", split=0.5, seed=7,
                images_per_placement=2, n_vehicles=10,
                camera=CameraConfig(width_px=128, height_px=128),
                render=RenderOptions(preset="fast"),
                simple_vehicles=True, gsd_range=(0.05, 0.3))
    base.update(kw)
    return ExportConfig(**base)


@pytest.fixture(scope="module")
def ranged(tiny_scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("gsd") / "one"
    export_dataset(_ranged(tiny_scene), out, workers=1, progress=False)
    return out


def test_each_image_has_its_gsd_in_header_and_metadata(ranged):
    man = json.loads((ranged / "manifest.json").read_text())
    assert man["parameters"]["gsd_range"] == [0.05, 0.3] and man["parameters"]["gsd_m"] is None
    cfg = ExportConfig.from_dict(man["parameters"])
    gsds = []
    for i in range(6):
        rec = meta.read(ranged / "meta" / f"{i:06d}.json")
        sp = "train" if i < 3 else "val"
        lab = dota.read(ranged / "dota" / sp / "labelTxt" / f"{i:06d}.txt")
        assert 0.05 <= rec.gsd_m <= 0.3
        assert lab.gsd_m == pytest.approx(rec.gsd_m, rel=1e-5)  # header = metadata
        assert rec.gsd_m == pytest.approx(image_gsd_m(cfg, i), rel=1e-5)  # the documented draw
        assert rec.camera["gsd_m"] == pytest.approx(rec.gsd_m, rel=1e-5)
        assert rec.camera["altitude_m"] == pytest.approx(rec.gsd_m * GsdRange.of(cfg).focal_px, rel=1e-5)
        gsds.append(rec.gsd_m)
    assert len(set(gsds)) == 6  # one draw per image


@pytest.mark.slow  # a second export on a 2-process pool (~20 s); the pool path itself is in
# the default set (tests/dataset/test_export.py)
def test_ranged_labels_identical_with_one_and_two_workers(ranged, tiny_scene, tmp_path):
    out2 = tmp_path / "two"
    export_dataset(_ranged(tiny_scene), out2, workers=2, progress=False)
    a, b = tree_bytes(ranged), tree_bytes(out2)
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []


def test_median_car_length_in_metres_is_the_same_at_every_gsd(tiny_scene, tmp_path):
    """Through ``stats``: the same view (same poses and vehicles: the frame's ground width
    is 30 m each time) at 0.05, 0.12 and 0.3 m GSD; the median small-vehicle box length in
    metres agrees within 3 % (the issue's bound). The width, 6 px at 0.3 m, is held to 6 %:
    half a pixel is 8 % of it."""
    med = {}
    for gsd, px in ((0.05, 600), (0.12, 250), (0.3, 100)):
        out = tmp_path / f"g{gsd}"
        cfg = ExportConfig(scene=tiny_scene, images=4, seed=3, images_per_placement=2,
                           n_vehicles=10, camera=CameraConfig(width_px=px, height_px=px, gsd_m=gsd),
                           render=RenderOptions(preset="fast"),
                           simple_vehicles=True)
        export_dataset(cfg, out, workers=1, progress=False)
        summary, arrays, _ = dataset_stats(out, classes=("small-vehicle",))
        assert summary["gsd_m"]["median"] == pytest.approx(gsd, rel=1e-4)
        assert len(arrays["length_m"]) >= 8
        med[gsd] = (float(np.median(arrays["length_m"])), float(np.median(arrays["width_m"])))
    for k, bound in ((0, 1.03), (1, 1.06)):
        vals = [m[k] for m in med.values()]
        assert max(vals) / min(vals) < bound, med
    assert 3.5 < med[0.05][0] < 6.0  # a car, in metres


def test_small_scene_narrows_the_top_of_the_range():
    """A 240 m x 200 m depot cannot hold a 0.3 m frame (307 m at 1024 px): its images draw
    over the part of the range whose frames fit, log-uniformly, never below the range."""
    from aerial_synth.dataset.gsd import FOOTPRINT_MARGIN, scene_cap_m

    cfg = ExportConfig(gsd_range=(0.05, 0.3), seed=2)
    depot = [[-120.0, -100.0], [120.0, 100.0]]
    cap = scene_cap_m(cfg, depot)
    assert cap == pytest.approx(200.0 / (1024 * FOOTPRINT_MARGIN))
    g = np.array([image_gsd_m(cfg, i, depot) for i in range(3000)])
    assert g.min() >= 0.05 and g.max() <= cap
    assert np.mean(g < math.sqrt(0.05 * cap)) == pytest.approx(0.5, abs=0.03)
    big = [[-1000.0, -1000.0], [1000.0, 1000.0]]
    assert [image_gsd_m(cfg, i, big) for i in range(50)] == [image_gsd_m(cfg, i) for i in range(50)]
    tiny = [[0.0, 0.0], [10.0, 10.0]]  # smaller than even the range's bottom: the bottom
    assert {image_gsd_m(cfg, i, tiny) for i in range(20)} == {0.05}
