"""CPU test of ``sim2real --plan`` (make test-train): 2 export arms x 2 seeds, --parallel 2,
1 epoch at imgsz 128, the network cut off. Asserts the report's spread and paired interval,
that parallel and sequential runs predict the same, that a second run reuses the exports
and the finished runs, and that ``sim2real score`` on the kept weights reproduces the AP."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.train
pytest.importorskip("ultralytics", reason="needs the [train] extra (Ultralytics, torch): make test-train")

from aerial_synth.evaluate.evaluation import read_task1_folder  # noqa: E402
from aerial_synth.evaluate.scoring import ScoringOptions, score  # noqa: E402
from aerial_synth.sim2real import report as rep  # noqa: E402
from aerial_synth.sim2real.confidence import paired_difference, spread  # noqa: E402
from aerial_synth.sim2real.real import read_real  # noqa: E402

from ..helpers import write_crossing_obj  # noqa: E402
from .test_train_smoke import _offline_cmd  # noqa: E402

ARM = ("{{export: {{scene: tiny.obj, images: 6, size: 128, gsd: {gsd}, split: 0.5, seed: {seed}, "
       "images_per_placement: 2, vehicles: 10, simple_vehicles: true}}}}")
PLAN = """real: real
baseline: A
seeds: [0, 1]
ignore_border: {{same: 2}}
real_scale: [arm, native]
train: {{epochs: 1, imgsz: 128, batch: 4, workers: 0, threads: 1}}
arms:
{arms}
"""
A = "  A: " + ARM.format(gsd=0.12, seed=3)
B = "  B: " + ARM.format(gsd="'0.10:0.14'", seed=4)


def _run(cwd: Path, *args):
    cmd, env, how = _offline_cmd(["sim2real", *args])
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900, cwd=cwd)
    assert r.returncode == 0, f"({how}) {r.stderr[-3000:]}"
    assert "NETWORK ATTEMPT" not in r.stderr
    return r


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """tiny.obj, a real collection (two groups: ``same`` at 0.12 m, ``coarse`` said to be at
    0.15 m) made from an export of the same scene, and the plans."""
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    root = tmp_path_factory.mktemp("plan")
    scene = write_crossing_obj(root / "tiny.obj", 40)
    cfg = ExportConfig(scene=scene, images=6, formats="dota", split=0.5, seed=9, images_per_placement=2,
                       n_vehicles=10, camera=CameraConfig(width_px=128, height_px=128, gsd_m=0.12),
                       simple_vehicles=True)
    export_dataset(cfg, root / "src", workers=1, progress=False)
    for grp, gsd in (("same", None), ("coarse", 0.15)):
        shutil.copytree(root / "src" / "dota" / "train", root / "real" / grp)
        if gsd is not None:
            for f in (root / "real" / grp / "labelTxt").glob("*.txt"):
                lines = [f"gsd:{gsd}" if ln.startswith("gsd:") else ln for ln in f.read_text().splitlines()]
                f.write_text("\n".join(lines) + "\n")
    shutil.rmtree(root / "src")
    (root / "plan.yaml").write_text(PLAN.format(arms=A + "\n" + B))
    (root / "plan_a.yaml").write_text(PLAN.format(arms=A))
    return root


@pytest.fixture(scope="module")
def run(folder):
    r = _run(folder, "--plan", "plan.yaml", "--out", "rep", "--parallel", "2", "--device", "cpu",
             "--export-workers", "1")
    return folder / "rep", json.loads((folder / "rep" / "report.json").read_text()), r


def _items(folder):
    return read_real(folder / "real", ("small-vehicle", "large-vehicle"))


def _agnostic(folder, items, pred_dir):
    dets = read_task1_folder(pred_dir, {g.name: i for i, g in enumerate(items)})
    return rep.agnostic(score(items, dets, ScoringOptions(("vehicle", None), "auto", {"same": 2.0})))


def test_report_spread_and_paired_interval(run, folder):
    out, report, r = run
    assert report["parallel"]["runs_at_once"] == 2 and report["plan"]["seeds"] == [0, 1]
    assert [a["name"] for a in report["arms"]] == ["A", "B"]
    items = _items(folder)
    curves = {}
    for a in report["arms"]:
        assert [x["seed"] for x in a["runs"]] == [0, 1] and a["training_images"] == 3
        assert a["export_seconds"] > 0 and a["export_reused"] is False
        assert a["workers_per_run"] == 0 and a["threads_per_run"] == 1
        for x in a["runs"]:
            assert x["epochs"] == 1 and x["images_per_s"] > 0 and x["peak_gpu_mib"] is None
            w = out / x["weights"]
            assert 1e6 < w.stat().st_size < 8e6  # half precision, no optimizer state
            # the report's AP is the AP of the prediction files it names
            c = _agnostic(folder, items, out / x["predictions"]["arm"])
            assert x["real_ap50"] == pytest.approx(c.ap, abs=1e-6)
        assert a["ap50"] == spread([x["real_ap50"] for x in a["runs"]])
        assert set(a["per_group"]) == {"coarse", "same"} and set(a["per_class"]) >= {"small-vehicle"}
        for g in a["per_group"]:
            assert a["per_group"][g] == spread([x["real"]["per_group"][g]["ap50"] for x in a["runs"]])
        curves[a["name"]] = [_agnostic(folder, items, out / x["predictions"]["arm"]) for x in a["runs"]]
    b = report["arms"][1]
    d = paired_difference(curves["B"], curves["A"]).to_dict()
    assert b["vs_baseline"] == d
    assert d["lo"] <= d["diff"] <= d["hi"] and d["level"] == 0.95
    assert d["verdict"] == ("no difference" if d["lo"] <= 0 <= d["hi"] else "better" if d["lo"] > 0 else "worse")
    assert "vs_baseline" not in report["arms"][0]
    summary = (out / "summary.txt").read_text()
    assert summary.startswith("aerial-synth sim2real --plan")
    assert next(ln for ln in summary.splitlines() if ln.startswith("B ")).endswith(d["verdict"])
    for f in ("pr.png", "contact_A.png", "contact_B.png", "plan.json"):
        assert (out / f).is_file(), f
    assert sorted(p.name for p in folder.iterdir()) == ["plan.yaml", "plan_a.yaml", "real", "rep", "tiny.obj"]


def test_parallel_equals_sequential(run, folder):
    """Arm A's two seeds one after the other (--parallel 1, another folder, its export made
    again): the same prediction files as when they ran beside each other."""
    out, report, _ = run
    _run(folder, "--plan", "plan_a.yaml", "--out", "seq", "--parallel", "1", "--device", "cpu",
         "--export-workers", "1")
    seq = json.loads((folder / "seq" / "report.json").read_text())
    assert seq["parallel"]["runs_at_once"] == 1
    for x, y in zip(report["arms"][0]["runs"], seq["arms"][0]["runs"]):
        for scale in ("arm", "native"):
            a, b = out / x["predictions"][scale], folder / "seq" / y["predictions"][scale]
            files = sorted(p.name for p in a.iterdir())
            assert files == sorted(p.name for p in b.iterdir()) and files
            for f in files:
                assert (a / f).read_bytes() == (b / f).read_bytes(), (scale, f)
        assert x["real_ap50"] == y["real_ap50"]
    shutil.rmtree(folder / "seq")


def test_second_run_reuses_exports_and_runs(run, folder):
    out, report, _ = run
    logs = {p: p.stat().st_mtime_ns for p in (out / "runs").rglob("log.txt")}
    _run(folder, "--plan", "plan.yaml", "--out", "rep", "--parallel", "2", "--device", "cpu")
    again = json.loads((out / "report.json").read_text())
    assert [a["export_reused"] for a in again["arms"]] == [True, True]
    assert {p: p.stat().st_mtime_ns for p in (out / "runs").rglob("log.txt")} == logs  # not trained again
    assert [a["ap50"] for a in again["arms"]] == [a["ap50"] for a in report["arms"]]
    assert again["arms"][1]["vs_baseline"] == report["arms"][1]["vs_baseline"]


def test_score_reproduces_the_runs_ap(run, folder):
    out, report, _ = run
    runs = [report["arms"][0]["runs"][0], report["arms"][1]["runs"][1]]
    _run(folder, "score", "--weights", *(str(out / x["weights"]) for x in runs), "--real", "real",
         "--out", "scored", "--device", "cpu", "--ignore-border", "same=2", "--real-scale", "arm,native")
    sc = json.loads((folder / "scored" / "report.json").read_text())
    assert [a["name"] for a in sc["arms"]] == ["A-seed0", "B-seed1"]
    for a, x in zip(sc["arms"], runs):
        assert a["real_ap50"] == x["real_ap50"] and a["real_recall"] == x["real_recall"]
        assert a["real"]["per_group"] == x["real"]["per_group"]
        for scale in ("arm", "native"):
            p, q = folder / "scored" / a["real_by_scale"][scale]["predictions"], out / x["predictions"][scale]
            for f in q.iterdir():
                assert (p / f.name).read_bytes() == f.read_bytes(), (scale, f.name)
    assert (folder / "scored" / "summary.txt").read_text().startswith("aerial-synth sim2real score")
    assert (folder / "scored" / "contact_A-seed0.png").is_file()
