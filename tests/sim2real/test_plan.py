"""sim2real --plan without torch: every plan rule and every bad-plan refusal (one line, exit
2, nothing written), the arm-kind registry, the parallel rule, the confidence figures."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aerial_synth.cli import main
from aerial_synth.evaluate.ap import Detections
from aerial_synth.evaluate.labels import ImageLabels
from aerial_synth.evaluate.scoring import ScoringOptions, score
from aerial_synth.sim2real import plan as plan_mod
from aerial_synth.sim2real import report as rep
from aerial_synth.sim2real import runs, ultra
from aerial_synth.sim2real.cli import export_argv, export_config
from aerial_synth.sim2real.confidence import paired_difference, spread, weighted_ap
from aerial_synth.sim2real.config import Sim2RealError
from aerial_synth.sim2real.plan import Built, PlanContext, arm_kind
from aerial_synth.sim2real.plan import load_plan as _load_plan

from ..helpers import REPO
from .conftest import box, write_real, write_synthetic


@pytest.fixture
def extra_present(monkeypatch):
    """Pretend the [train] extra is installed: every check before training still runs."""
    monkeypatch.setattr(ultra, "require_train_extra", lambda: None)


@pytest.fixture
def folder(tmp_path):
    """A real set and two synthetic sets beside the plan."""
    write_real(tmp_path / "real", "r", [box(10, 10, 30, 20)])
    write_synthetic(tmp_path / "s1")
    write_synthetic(tmp_path / "s2", gsd=0.2)
    return tmp_path


GOOD = """real: real
baseline: A
seeds: [0, 1]
train: {epochs: 1, imgsz: 128, batch: 4}
arms:
  A: {synthetic: s1}
  B: {synthetic: [s2], train: {minutes: 2}}
"""


def load_plan(path):
    return _load_plan(path, export_config=export_config)  # the export parser, as the CLI gives it


def _write(folder: Path, text: str) -> Path:
    p = folder / "plan.yaml"
    p.write_text(text)
    return p


def _refused(capsys, folder, text, *extra):
    out = folder / "out"
    rc = main(["sim2real", "--plan", str(_write(folder, text)), "--out", str(out), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, err
    assert len(err) == 1, err
    assert not out.exists(), "a refused plan wrote something"
    return err[0]


def test_good_plan_rules(folder):
    p = load_plan(_write(folder, GOOD))
    assert p.baseline == "A" and p.seeds == (0, 1) and [a.name for a in p.arms] == ["A", "B"]
    a, b = p.arm("A"), p.arm("B")
    assert a.kind == "synthetic" and a.spec == (folder / "s1",)  # relative to the plan's folder
    assert a.train.epochs == 1 and a.train.minutes is None and a.train.imgsz == 128
    assert b.train.minutes == 2 and b.train.epochs is None and b.train.imgsz == 128  # an arm overrides
    assert p.configs["B"].minutes == 2 and p.configs["A"].epochs == 1 and p.configs["A"].tile == 128


def test_baseline_defaults_to_the_first_arm_and_real_options_are_keys(folder):
    text = GOOD.replace("baseline: A\n", "") + "ignore_border: {r: 3}\nreal_scale: [native, arm]\niou_type: obb\n"
    write_real(folder / "real2" / "r", "x", [box(10, 10, 30, 20)])
    p = load_plan(_write(folder, text.replace("real: real", "real: real2")))
    assert p.baseline == "A"
    cfg = p.configs["A"]
    assert cfg.ignore_border == {"r": 3.0} and cfg.real_scale == ("native", "arm") and cfg.iou_type == "obb"


@pytest.mark.parametrize("edit, expect", [
    (("seeds: [0, 1]", "seeds: [0, 1]\nbogus: 1"), "unknown key 'bogus'"),
    (("{epochs: 1,", "{epoch: 1,"), "train: unknown key 'epoch'"),
    (("A: {synthetic: s1}", "A: {synthetic: s1, colour: red}"), "arm A: unknown key 'colour'"),
    (("B: {synthetic: [s2], train: {minutes: 2}}", "A: {synthetic: s2}"), "expected YAML with each key once in a mapping, got 'A' twice"),
    (("baseline: A", "baseline: Z"), "baseline 'Z' is not an arm"),
    (("seeds: [0, 1]", "seeds: []"), "seeds: expected a non-empty list"),
    (("seeds: [0, 1]", "seeds: [1, 1]"), "seeds: expected distinct integers"),
    (("real: real\n", ""), "missing key 'real'"),
    (("real: real", "real: nowhere"), "real " + "{folder}/nowhere: no such folder"),
    (("A: {synthetic: s1}", "A: {synthetic: s1, export: {images: 2}}"), "arm A: expected exactly one of"),
    (("A: {synthetic: s1}", "A: {synthetic: missing}"), "arm A: synthetic {folder}/missing: no such folder"),
    (("A: {synthetic: s1}", "A: {export: {images: 0}}"), "arm A: export: aerial-synth export: --images: expected"),
    (("A: {synthetic: s1}", "A: {export: {gsd: '0.3:0.05'}}"), "arm A: export: aerial-synth export: --gsd: expected"),
    (("A: {synthetic: s1}", "A: {export: {sky: blue}}"), "arm A: export: unknown option 'sky'"),
    (("A: {synthetic: s1}", "A: {export: {out: x}}"), "arm A: export: 'out' is set by sim2real"),
    (("A: {synthetic: s1}", "A: {export: {simple_vehicles: 3}}"), "simple_vehicles: expected true or false"),
    (("{epochs: 1,", "{epochs: 1, minutes: 3,"), "expected --minutes or --epochs, not both"),
    (("seeds: [0, 1]", "seeds: [0, 1]\nignore_classes: {r: large-vehicle}"), "ignore_classes: expected a mapping"),
    (("seeds: [0, 1]", "seeds: [0, 1]\nignore_classes: {ucas: [large-vehicle]}"), "ignore_classes: no group 'ucas'"),
    (("imgsz: 128", "imgsz: 100"), "--imgsz: expected a multiple of 32"),
    (("seeds: [0, 1]", "seeds: [0, 1]\nignore_border: {nogroup: 4}"), "no group 'nogroup'"),
])
def test_bad_plan_is_one_line_and_writes_nothing(folder, capsys, extra_present, edit, expect):
    text = GOOD.replace(*edit)
    assert text != GOOD
    msg = _refused(capsys, folder, text)
    assert "--plan " in msg and expect.format(folder=folder) in msg, msg


def test_bad_export_option_is_the_exports_own_message(folder, capsys, extra_present, tmp_path):
    """The message of `export --gsd 0.3:0.05` itself, prefixed with the arm's name."""
    r = subprocess.run([sys.executable, "-m", "aerial_synth.cli", "export", "--gsd", "0.3:0.05",
                        "--out", str(tmp_path / "x")], capture_output=True, text=True, cwd=REPO, timeout=120)
    own = r.stderr.strip().split("aerial-synth export: ", 1)[1]
    msg = _refused(capsys, folder, GOOD.replace("A: {synthetic: s1}", "A: {export: {gsd: '0.3:0.05'}}"))
    assert msg.endswith("arm A: export: aerial-synth export: " + own), (msg, own)


def test_not_a_plan(folder, capsys, extra_present):
    assert "broken YAML" in _refused(capsys, folder, "real: [unclosed\n")
    assert "expected a mapping" in _refused(capsys, folder, "- a\n- b\n")
    assert "arms: expected a mapping" in _refused(capsys, folder, "real: real\narms: {}\n")
    out = folder / "o"
    rc = main(["sim2real", "--plan", str(folder / "none.yaml"), "--out", str(out)])
    assert rc == 2 and "no such file" in capsys.readouterr().err and not out.exists()


def test_a_plan_is_checked_without_the_train_extra(folder):
    """Without Ultralytics a bad plan still gets its own line; a good one the install hint."""
    def run(text):
        plan = _write(folder, text)
        code = ("import sys; sys.modules['ultralytics'] = None; from aerial_synth.cli import main; "
                f"sys.exit(main(['sim2real', '--plan', {str(plan)!r}, '--out', {str(folder / 'out')!r}]))")
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not (folder / "out").exists()
        return r.stderr
    assert "baseline 'Z' is not an arm" in run(GOOD.replace("baseline: A", "baseline: Z"))
    assert "pip install 'aerial-synth[train]'" in run(GOOD)


def test_plan_with_one_off_flags_is_refused(folder, capsys, extra_present):
    msg = _refused(capsys, folder, GOOD, "--epochs", "3")
    assert "--epochs comes from the plan" in msg


def test_out_must_be_new_or_a_plan_folder(folder, capsys, extra_present):
    out = folder / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    rc = main(["sim2real", "--plan", str(_write(folder, GOOD)), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "not a sim2real plan folder" in err[0]
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]
    rc = main(["sim2real", "--plan", str(_write(folder, GOOD)), "--out", str(folder / "real" / "o")])
    assert rc == 2 and "overlaps the input folder real" in capsys.readouterr().err


def test_export_arm_options_map_to_the_export_command(folder):
    """'-' written '_', true a flag, false left out, a list a comma list; yolo-obb added."""
    argv = export_argv("A", {"scene_mix": "default", "gsd": "0.05:0.3", "simple_vehicles": True,
                                      "box_fit": "contour", "distractors": 0, "format": ["dota"]})
    assert argv == ["--scene-mix", "default", "--gsd", "0.05:0.3", "--simple-vehicles", "--box-fit", "contour",
                    "--distractors", "0", "--format", "dota,yolo-obb"]
    assert "--simple-vehicles" not in export_argv("A", {"simple_vehicles": False})
    p = load_plan(_write(folder, GOOD.replace("A: {synthetic: s1}",
                                              "A: {export: {scene_mix: default, gsd: '0.05:0.3', images: 7}}")))
    cfg = p.arm("A").spec
    assert cfg.images == 7 and cfg.gsd_range == (0.05, 0.3) and "city_park/jam:2" in cfg.scene_mix
    assert "yolo-obb" in cfg.formats


def test_a_new_arm_kind_is_one_registration(folder, monkeypatch):
    """The registry: a toy kind (as issue 34's stream: arms will be) plugs in with (check, build)."""
    monkeypatch.setattr(plan_mod, "ARM_KINDS", dict(plan_mod.ARM_KINDS))
    seen = []

    @arm_kind("toy")
    def _toy():
        def check(arm, value, ctx):
            seen.append((arm, value))
            return ctx.plan_dir / value

        return check, lambda spec, folder, workers: Built((spec,))

    p = load_plan(_write(folder, GOOD.replace("A: {synthetic: s1}", "A: {toy: s1}")))
    assert seen == [("A", "s1")] and p.arm("A").kind == "toy" and p.arm("A").spec == folder / "s1"
    assert plan_mod.ARM_KINDS["toy"].build(p.arm("A").spec, folder, 1).dirs == (folder / "s1",)


def test_export_arm_is_reused_by_its_manifest(tmp_path):
    """build() exports once; a second build with the same options reuses the folder; other
    options export again (resumed with --force semantics)."""
    from ..helpers import write_crossing_obj

    scene = write_crossing_obj(tmp_path / "tiny.obj", 20)
    opts = {"scene": scene, "images": 2, "size": 64, "simple_vehicles": True, "vehicles": 2}
    kind = plan_mod.ARM_KINDS["export"]
    ctx = PlanContext(tmp_path, export_config)
    cfg = kind.check("A", opts, ctx)
    b1 = kind.build(cfg, tmp_path / "exp", 1)
    assert not b1.reused and (tmp_path / "exp" / "yolo-obb" / "data.yaml").is_file()
    stamp = (tmp_path / "exp" / "manifest.json").stat().st_mtime_ns
    b2 = kind.build(kind.check("A", opts, ctx), tmp_path / "exp", 1)
    assert b2.reused and b2.seconds == 0.0
    assert (tmp_path / "exp" / "manifest.json").stat().st_mtime_ns == stamp
    b3 = kind.build(kind.check("A", dict(opts, images=3), ctx), tmp_path / "exp", 1)
    assert not b3.reused and len(list((tmp_path / "exp" / "yolo-obb" / "images").rglob("*.png"))) == 3


# -- parallel rule -----------------------------------------------------------------------------------

def test_auto_parallel_and_shares(monkeypatch):
    from aerial_synth.sim2real.plan import TrainSpec

    monkeypatch.setattr(runs, "cores", lambda: 16)
    n, why = runs.auto_parallel(18, "cpu", [TrainSpec()])
    assert n == 4 and "16 cores / 4" in why
    monkeypatch.setattr(ultra, "free_gpu_gib", lambda d: (130.0, 139.0))
    n, why = runs.auto_parallel(18, "cuda:0", [TrainSpec(batch=16, imgsz=640)])
    per = runs.gpu_estimate_gib(16, 640)
    assert n == min(8, int((130 - 2) // per)) == 8 and "GiB free" in why
    monkeypatch.setattr(ultra, "free_gpu_gib", lambda d: (12.0, 16.0))
    assert runs.auto_parallel(18, "cuda:0", [TrainSpec(batch=16, imgsz=640)])[0] == int(10 // per)
    assert runs.auto_parallel(1, "cuda:0", [TrainSpec()])[0] == 1
    assert runs.share_out(4, None, None) == (3, 4)    # (16 - 4) // 4 loader workers, 16 // 4 threads
    assert runs.share_out(4, 0, 1) == (0, 1)          # the plan's own values are kept
    assert runs.share_out(1, None, None) == (8, 16)   # at most 8 loader workers


def test_a_finished_run_is_reused_only_whole_and_with_its_spec(tmp_path):
    """result.json is read through safe_input: missing, cut short by a killed run, a folder
    or another spec's means "run it again" (None), never an exception."""
    from aerial_synth.io_utils import atomic_write_json

    spec = {"arm": "A", "seed": 0, "run_dir": str(tmp_path)}
    res = tmp_path / "result.json"
    assert runs.finished(tmp_path, spec) is None  # no result yet
    atomic_write_json(res, {"spec": spec, "epochs": 3})
    assert runs.finished(tmp_path, spec) == {"spec": spec, "epochs": 3}
    assert runs.finished(tmp_path, dict(spec, seed=1)) is None  # another spec
    res.write_bytes(res.read_bytes()[:20])  # killed while written
    assert runs.finished(tmp_path, spec) is None
    res.unlink()
    res.mkdir()
    assert runs.finished(tmp_path, spec) is None


# -- confidence --------------------------------------------------------------------------------------

def _truth(n_img=12):
    """4 boxes per image."""
    return [ImageLabels(f"im{i}", np.array([box(20 * k + 2, 5, 20 * k + 14, 12) for k in range(4)]),
                        ["car"] * 4, np.zeros(4, bool), None, None, size_wh=(100, 60))
            for i in range(n_img)]


def _dets(gt, rng, hit_rate, n_fp):
    """The truth jittered (each box found with ``hit_rate``) plus ``n_fp`` false positives per image."""
    img, sc, xy = [], [], []
    for i, g in enumerate(gt):
        for b in g.polygons_xy_px:
            if rng.random() < hit_rate:
                img.append(i), sc.append(rng.random()), xy.append(b + rng.normal(0, 0.3, (4, 2)))
        for _ in range(n_fp):
            x = rng.uniform(0, 80)
            img.append(i), sc.append(rng.random()), xy.append(box(x, 40, x + 10, 47))
    return Detections(np.array(img), ["car"] * len(img), np.array(sc), np.array(xy))


def _agn(gt, d):
    return rep.agnostic(score(gt, d, ScoringOptions(("vehicle", None), "obb")))


def test_weighted_ap_with_unit_weights_is_the_scorers_ap():
    rng = np.random.default_rng(1)
    gt = _truth()
    for hit, fp in ((0.9, 1), (0.5, 3), (0.0, 2), (1.0, 0)):
        c = _agn(gt, _dets(gt, rng, hit, fp))
        assert weighted_ap(c, np.ones((1, len(gt))))[0] == pytest.approx(c.ap, abs=1e-12)
    # doubling every image's weight changes nothing; dropping images gives the AP of the rest
    c = _agn(gt, _dets(gt, rng, 0.7, 2))
    assert weighted_ap(c, np.full((1, len(gt)), 2.0))[0] == pytest.approx(c.ap, abs=1e-12)
    d = _dets(gt, rng, 0.7, 2)
    m = d.image < 6
    sub = _agn(gt[:6], Detections(d.image[m], ["car"] * int(m.sum()), d.scores[m], d.polygons_xy_px[m]))
    w = np.zeros((1, len(gt)))
    w[0, :6] = 1
    assert weighted_ap(_agn(gt, d), w)[0] == pytest.approx(sub.ap, abs=1e-12)


def test_paired_difference_verdicts():
    rng = np.random.default_rng(2)
    gt = _truth(20)
    good = [_agn(gt, _dets(gt, rng, 0.95, 0)) for _ in range(3)]
    bad = [_agn(gt, _dets(gt, rng, 0.3, 4)) for _ in range(3)]
    same = paired_difference(good, good)
    assert same.diff == 0 and same.lo == 0 and same.hi == 0 and same.verdict == "no difference"
    d = paired_difference(good, bad)
    assert d.diff == pytest.approx(np.mean([c.ap for c in good]) - np.mean([c.ap for c in bad]))
    assert 0 < d.lo <= d.diff <= d.hi and d.verdict == "better"
    assert paired_difference(bad, good).verdict == "worse"
    assert paired_difference(good, bad).to_dict() == d.to_dict()  # a fixed RNG: reproducible
    # two draws of the same detector: the interval holds 0
    a = [_agn(gt, _dets(gt, np.random.default_rng(s), 0.6, 2)) for s in (10, 11, 12)]
    b = [_agn(gt, _dets(gt, np.random.default_rng(s), 0.6, 2)) for s in (20, 21, 22)]
    nd = paired_difference(a, b)
    assert nd.lo < 0 < nd.hi and nd.verdict == "no difference"
    with pytest.raises(ValueError):
        paired_difference(a, b[:2])


def test_spread():
    s = spread([0.2, 0.4, None])
    assert s["mean"] == pytest.approx(0.3) and s["sd"] == pytest.approx(np.std([0.2, 0.4], ddof=1), abs=1e-6)
    assert spread([0.5])["sd"] == 0.0 and spread([None])["mean"] is None


def test_plan_summary_says_no_difference():
    arm = {"name": "A", "kind": "export", "training_images": 10, "export_seconds": 3.0, "export_reused": False,
           "images_per_s": {"mean": 12.0}, "runs": [{"epochs": 1}], "ap50": spread([0.5, 0.6]),
           "per_group": {"g": spread([0.5, 0.6])}, "per_class": {"car": spread([0.5, 0.6])}}
    b = dict(arm, name="B", export_reused=True,
             vs_baseline={"diff": 0.01, "lo": -0.05, "hi": 0.07, "verdict": "no difference"})
    report = {"plan": {"path": "p.yaml", "seeds": [0, 1], "baseline": "A"},
              "device": {"name": "cpu", "used": "cpu"},
              "parallel": {"runs_at_once": 2, "rule": "--parallel 2", "wall_seconds": 10.0},
              "real": {"dir": "real", "images": 3, "vehicles": 9},
              "confidence": {"level": 0.95, "method": "paired bootstrap"}, "arms": [arm, b]}
    text = rep.plan_summary_text(report)
    row = next(ln for ln in text.splitlines() if ln.startswith("B "))
    assert "+0.010 [-0.050, +0.070]" in row and row.endswith("no difference") and "reused" in row
    assert "0.550 ± 0.071" in row


def test_score_needs_weights_and_real(tmp_path, capsys, extra_present):
    real = write_real(tmp_path / "real", "r", [box(10, 10, 30, 20)])
    out = tmp_path / "out"
    rc = main(["sim2real", "score", "--weights", str(tmp_path / "no.pt"), "--real", str(real), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no.pt: no such file" in err[0] and not out.exists()
    rc = main(["sim2real", "score", "--real", str(real), "--out", str(out)])
    assert rc == 2 and "--weights" in capsys.readouterr().err and not out.exists()


def test_sim2real_without_plan_or_sets(tmp_path, capsys, extra_present):
    rc = main(["sim2real", "--out", str(tmp_path / "o")])
    assert rc == 2 and "expected --plan PLAN.yaml, or --synthetic" in capsys.readouterr().err


def test_plan_errors_are_sim2real_errors(folder):
    with pytest.raises(Sim2RealError, match="baseline"):
        load_plan(_write(folder, GOOD.replace("baseline: A", "baseline: Q")))


def test_drop_classes_only_on_the_named_group():
    from aerial_synth.sim2real.experiment import drop_classes

    gt = [ImageLabels(f"{g}/im", np.zeros((0, 4, 2)), [], np.zeros(0, bool), None, None, size_wh=(10, 10),
                      extra={"group": g}) for g in ("ucas", "minsk")]
    d = Detections(np.array([0, 0, 1, 1]), ["large-vehicle", "small-vehicle", "large-vehicle", "small-vehicle"],
                   np.array([0.9, 0.8, 0.7, 0.6]), np.zeros((4, 4, 2)))
    kept = drop_classes(gt, d, {"ucas": ("large-vehicle",)})
    assert kept.classes == ["small-vehicle", "large-vehicle", "small-vehicle"]
    assert kept.image.tolist() == [0, 1, 1] and kept.scores.tolist() == [0.8, 0.7, 0.6]
    assert drop_classes(gt, d, {}) is d


def test_weighted_ap_is_the_ap_of_the_resampled_set():
    """Image weights = images drawn that often: the AP of a set built from the drawn images
    (each copy with its detections) equals weighted_ap with those weights."""
    rng = np.random.default_rng(7)
    gt = _truth(10)
    d = _dets(gt, rng, 0.6, 3)
    c = _agn(gt, d)
    for _ in range(5):
        drawn = rng.integers(0, len(gt), len(gt))
        w = np.bincount(drawn, minlength=len(gt)).astype(float)
        gt2, img, sc, xy = [], [], [], []
        for k, i in enumerate(drawn):
            gt2.append(gt[i])
            m = d.image == i
            img += [k] * int(m.sum())
            sc += d.scores[m].tolist()
            xy.append(d.polygons_xy_px[m])
        ref = _agn(gt2, Detections(np.array(img), ["car"] * len(img), np.array(sc), np.concatenate(xy)))
        assert weighted_ap(c, w[None])[0] == pytest.approx(ref.ap, abs=1e-12)


# -- stream arms -------------------------------------------------------------------------------------

STREAM = "A: {stream: {scene: city_park, scenario: jam, images: 6, size: 128, gsd: 0.12, seed: 5, pool: 4, refresh: 0.5}}"


def test_stream_arm_is_an_export_config_and_a_pool(folder):
    p = load_plan(_write(folder, GOOD.replace("A: {synthetic: s1}", STREAM)))
    a = p.arm("A")
    assert a.kind == "stream" and isinstance(a.spec, plan_mod.StreamArm)
    assert a.spec.config.images == 6 and a.spec.config.seed == 5 and a.spec.config.camera.width_px == 128
    assert a.spec.pool == 4 and a.spec.refresh == 0.5 and a.spec.gsd_m == pytest.approx(0.12)
    # the same options as an export arm give the same ExportConfig
    e = load_plan(_write(folder, GOOD.replace("A: {synthetic: s1}", STREAM.replace("stream", "export")
                                              .replace(", pool: 4, refresh: 0.5", ""))))
    assert e.arm("A").spec == a.spec.config
    # build writes nothing: the runs render; its stand-in set has the detection classes
    b = plan_mod.ARM_KINDS["stream"].build(a.spec, folder / "exports" / "A", 1)
    assert not (folder / "exports").exists() and b.dirs == () and b.images == 4
    assert b.stream["pool"] == 4 and b.stream["config"]["seed"] == 5 and b.sets[0].gsd_m == pytest.approx(0.12)
    assert "small-vehicle" in b.sets[0].names
    # a GSD range has no single GSD
    r = load_plan(_write(folder, GOOD.replace("A: {synthetic: s1}", "A: {stream: {gsd: '0.05:0.3', images: 3}}")))
    assert r.arm("A").spec.gsd_m is None and r.arm("A").spec.pool is None


def test_stream_seed_differs_by_run_seed_and_export_seed():
    s = {plan_mod.stream_seed(e, r) for e in (0, 1) for r in (0, 1, 2)}
    assert len(s) == 6 and all(0 <= x < 2**63 for x in s)
    assert plan_mod.stream_seed(3, 1) == plan_mod.stream_seed(3, 1)


@pytest.mark.parametrize("arm, expect", [
    ("A: {stream: {images: 0}}", "arm A: stream: aerial-synth export: --images: expected"),
    ("A: {stream: {gsd: '0.3:0.05'}}", "arm A: stream: aerial-synth export: --gsd: expected"),
    ("A: {stream: {sky: blue}}", "arm A: stream: unknown option 'sky'"),
    ("A: {stream: {out: x}}", "arm A: stream: 'out' is set by sim2real"),
    ("A: {stream: {scene: nowhere_scene}}", "arm A: stream: "),
    ("A: {stream: [1, 2]}", "arm A: stream: expected a mapping of export options"),
    ("A: {stream: {images: 4, pool: 5}}", "arm A: stream: pool: expected an integer in 1..4"),
    ("A: {stream: {images: 4, pool: true}}", "arm A: stream: pool: expected an integer"),
    ("A: {stream: {images: 4, pool: 2, refresh: 1.5}}", "arm A: stream: refresh: expected a number in 0..1"),
    ("A: {stream: {images: 4, refresh: 0.5}}", "arm A: stream: refresh: only with pool"),
    ("A: {stream: {images: 4}, synthetic: s1}", "arm A: expected exactly one of"),
])
def test_bad_stream_arm_is_one_line_and_writes_nothing(folder, capsys, extra_present, arm, expect):
    msg = _refused(capsys, folder, GOOD.replace("A: {synthetic: s1}", arm))
    assert "--plan " in msg and expect in msg, msg


def test_stream_arm_message_is_the_exports_own(folder, capsys, extra_present, tmp_path):
    """The message of `export --gsd 0.3:0.05` itself, after ``arm A: stream:``."""
    r = subprocess.run([sys.executable, "-m", "aerial_synth.cli", "export", "--gsd", "0.3:0.05",
                        "--out", str(tmp_path / "x")], capture_output=True, text=True, cwd=REPO, timeout=120)
    own = r.stderr.strip().split("aerial-synth export: ", 1)[1]
    msg = _refused(capsys, folder, GOOD.replace("A: {synthetic: s1}", "A: {stream: {gsd: '0.3:0.05'}}"))
    assert msg.endswith("arm A: stream: aerial-synth export: " + own), (msg, own)


def test_stream_arm_with_a_gsd_range_needs_gsd_for_arm_scale(folder, capsys, extra_present):
    text = GOOD.replace("A: {synthetic: s1}", "A: {stream: {gsd: '0.05:0.3', images: 3}}") + "real_scale: [arm]\n"
    msg = _refused(capsys, folder, text)
    assert "arm A: no single GSD (a GSD or altitude range); give the arm gsd: M" in msg, msg
