"""CPU smoke test of the whole sim2real loop (make test-train): a tiny export, 1 epoch at
imgsz 128, the network cut off. Marked ``train`` (deselected by default) and skipped, with
the reason, where Ultralytics is not installed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.train
pytest.importorskip("ultralytics", reason="needs the [train] extra (Ultralytics, torch): make test-train")

from aerial_synth.cli import main  # noqa: E402
from aerial_synth.sim2real import pipeline, ultra  # noqa: E402
from aerial_synth.sim2real.config import Sim2RealConfig, parse_arms  # noqa: E402
from aerial_synth.sim2real.report import ARM_FIELDS, REPORT_FIELDS  # noqa: E402

from ..helpers import REPO, write_crossing_obj  # noqa: E402


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A 6-image export (128 px, box vehicles, yolo-obb + dota) and a real collection made of
    its validation images: group ``same`` at the synthetic GSD, group ``coarse`` labelled at
    a coarser GSD (so it is rescaled, 0.15 / 0.12)."""
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    root = tmp_path_factory.mktemp("sim2real")
    scene = write_crossing_obj(root / "tiny.obj", 40)
    syn = root / "syn"
    cfg = ExportConfig(scene=scene, images=6, formats="yolo-obb,dota", split=0.5, seed=3,
                       images_per_placement=2, n_vehicles=10,
                       camera=CameraConfig(width_px=128, height_px=128, gsd_m=0.12),
                       simple_vehicles=True)
    export_dataset(cfg, syn, workers=1, progress=False)
    real = root / "real"
    for grp, gsd in (("same", None), ("coarse", 0.15)):
        shutil.copytree(syn / "dota" / "val", real / grp)
        if gsd is not None:
            for f in (real / grp / "labelTxt").glob("*.txt"):
                lines = [f"gsd:{gsd}" if ln.startswith("gsd:") else ln for ln in f.read_text().splitlines()]
                f.write_text("\n".join(lines) + "\n")
    return syn, real


# Every attempt to reach the network (a name lookup or a connect to anything but a local
# socket) is written to stderr with its stack and refused; the tests require none.
_GUARD = """
import socket, sys, traceback
def _refuse(what):
    sys.stderr.write("NETWORK ATTEMPT: " + what + "\\n" + "".join(traceback.format_stack(limit=25)))
    raise OSError("network blocked by the sim2real smoke test")
_gai = socket.getaddrinfo
def getaddrinfo(host, *a, **k):
    if host not in (None, "localhost", "127.0.0.1", "::1"):
        _refuse("getaddrinfo " + repr(host))
    return _gai(host, *a, **k)
socket.getaddrinfo = getaddrinfo
socket.gethostbyname = lambda host: _refuse("gethostbyname " + repr(host))
_connect = socket.socket.connect
def connect(self, addr):
    if self.family != socket.AF_UNIX:
        _refuse("connect " + repr(addr))
    return _connect(self, addr)
socket.socket.connect = connect
from aerial_synth.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _offline_cmd(args):
    """The CLI with the guard above, in a process without network: `unshare -rn` where it
    works, else every proxy variable pointing at a closed local port."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-c", _GUARD, *map(str, args)]
    if shutil.which("unshare") and subprocess.run(["unshare", "-rn", "true"], capture_output=True).returncode == 0:
        return ["unshare", "-rn", *cmd], env, "unshare -rn"
    for k in ("HTTP_PROXY", "HTTPS_PROXY", "http_proxy", "https_proxy", "ALL_PROXY", "all_proxy"):
        env[k] = "http://127.0.0.1:9"
    env.pop("NO_PROXY", None)
    env.pop("no_proxy", None)
    return cmd, env, "dead proxy"


SMOKE = ["--epochs", "1", "--imgsz", "128", "--device", "cpu", "--workers", "0", "--seed", "0",
         "--conf", "0.001", "--batch", "4", "--ignore-border", "same=2", "--real-scale", "arm,native"]


@pytest.fixture(scope="module")
def smoke(data, tmp_path_factory):
    """Two arms on the same data, run from a scratch folder with a relative --out."""
    syn, real = data
    cwd = tmp_path_factory.mktemp("run")
    cmd, env, how = _offline_cmd(["sim2real", "--synthetic", f"a={syn}", "--synthetic", f"b={syn}",
                                  "--real", real, "--out", "report", *SMOKE])
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600, cwd=cwd)
    assert r.returncode == 0, f"({how}) {r.stderr[-3000:]}"
    assert "NETWORK ATTEMPT" not in r.stderr, r.stderr[r.stderr.index("NETWORK ATTEMPT"):][:3000]
    assert sorted(p.name for p in cwd.iterdir()) == ["report"], "something written beside --out"
    return cwd / "report", r


def test_report_holds_every_field(smoke, data):
    out, r = smoke
    rep = json.loads((out / "report.json").read_text())
    assert set(REPORT_FIELDS) <= set(rep)
    assert [a["name"] for a in rep["arms"]] == ["a", "b"]
    for a in rep["arms"]:
        assert set(ARM_FIELDS) <= set(a)
        assert a["training_images"] == 3 and a["validation_images"] == 3 and a["epochs"] == 1
        assert a["seconds"] > 0 and a["synthetic_val_map50"] is not None
        assert 0.0 <= a["real_ap50"] <= 1.0 and 0.0 <= a["real_recall"] <= 1.0
        assert set(a["real"]["per_group"]) == {"coarse", "same"}
        assert (out / a["predictions"] / "Task1_small-vehicle.txt").is_file()
        assert (out / a["weights"]).is_file()
    assert rep["versions"]["ultralytics"] == "8.4.190"
    assert rep["versions"]["torch"] and rep["versions"]["aerial_synth"]
    assert rep["device"]["used"] == "cpu" and rep["device"]["name"].startswith("CPU")
    assert rep["real"]["groups"]["coarse"]["images"] == 3
    assert rep["scoring"]["ignore_border_px_by_group"] == {"coarse": 0.0, "same": 2.0}
    for f in ["summary.txt", "pr.png", "pr_coarse.png", "pr_same.png", "contact_a.png", "contact_b.png"]:
        assert (out / f).is_file(), f
    assert (out / "pr.png").read_bytes()[:4] == b"\x89PNG"
    summary = (out / "summary.txt").read_text()
    assert "real AP50" in summary and "8.4.190" in summary
    assert not list(out.parent.glob(".report.*")), "temporary folders left behind"
    assert not list((data[0] / "yolo-obb" / "labels").glob("*.cache")), "label cache written into the export"


def test_native_scale_scores_the_same_weights_unscaled(smoke, data, tmp_path):
    """--real-scale arm,native: the headline is the rescaled one; group ``same`` is at the
    synthetic GSD, so its predictions and figures are the same both ways, while ``coarse``
    (rescaled by 0.15 / 0.12 for the arm scale) is predicted on other pixels; eval on the
    native prediction files gives the native figures."""
    out, _ = smoke
    _, real = data
    rep = json.loads((out / "report.json").read_text())
    assert rep["parameters"]["real_scale"] == ["arm", "native"]
    a = rep["arms"][0]
    by = a["real_by_scale"]
    assert list(by) == ["arm", "native"] and a["real_scale"] == "arm"
    assert by["arm"]["ap50"] == a["real_ap50"] and by["arm"]["gsd_m"] == a["gsd_m"]
    assert by["native"]["gsd_m"] is None
    assert by["native"]["predictions"].endswith("predictions_native")
    assert by["native"]["real"]["per_group"]["same"] == by["arm"]["real"]["per_group"]["same"]

    def rows(folder, group):
        return sorted(ln for f in sorted((out / folder).glob("Task1_*.txt"))
                      for ln in f.read_text().splitlines() if ln.startswith(group + "/"))
    assert rows(by["arm"]["predictions"], "same") == rows(by["native"]["predictions"], "same")
    assert rows(by["arm"]["predictions"], "coarse") != rows(by["native"]["predictions"], "coarse")
    rc = main(["eval", "--gt", str(real), "--pred", str(out / by["native"]["predictions"]),
               "--merge-classes", "vehicle", "--iou-type", "auto", "--ignore-border", "same=2",
               "--out", str(tmp_path / "ev")])
    assert rc == 0
    ev = json.loads((tmp_path / "ev" / "eval.json").read_text())
    assert ev["overall"]["ap"]["vehicle"] == pytest.approx(by["native"]["ap50"], abs=1e-6)
    assert "--real-scale native" in (out / "summary.txt").read_text()


def test_independent_rescoring_agrees(smoke, data, tmp_path, capsys):
    out, _ = smoke
    _, real = data
    rep = json.loads((out / "report.json").read_text())
    a = rep["arms"][0]
    rc = main(["eval", "--gt", str(real), "--pred", str(out / a["predictions"]), "--merge-classes",
               "vehicle", "--iou-type", "auto", "--ignore-border", "same=2", "--out", str(tmp_path / "ev")])
    assert rc == 0
    ev = json.loads((tmp_path / "ev" / "eval.json").read_text())
    assert ev["overall"]["ap"]["vehicle"] == pytest.approx(a["real_ap50"], abs=1e-6)
    for g, fig in a["real"]["per_group"].items():
        assert ev["groups"][g]["ap"]["vehicle"] == pytest.approx(fig["ap50"], abs=1e-6)
        assert ev["groups"][g]["per_threshold"]["0.50"]["vehicle"]["n_det"] == fig["n_det"]


def test_same_seed_same_predictions(smoke, data, tmp_path):
    """Arms a and b (same data, same seed, one process) and a second process give identical
    prediction files."""
    out, _ = smoke
    syn, real = data
    files = sorted((out / "arms" / "a" / "predictions").glob("*.txt"))
    assert sum(len(f.read_text().splitlines()) for f in files) > 0, "no predictions to compare"
    for f in files:
        assert f.read_bytes() == (out / "arms" / "b" / "predictions" / f.name).read_bytes(), f.name
    out2 = tmp_path / "again"
    cmd, env, how = _offline_cmd(["sim2real", "--synthetic", f"a={syn}", "--real", real, "--out", out2, *SMOKE])
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "NETWORK ATTEMPT" not in r.stderr
    for f in files:
        assert f.read_bytes() == (out2 / "arms" / "a" / "predictions" / f.name).read_bytes(), f.name


def test_perfect_predictions_give_ap_one(data, smoke, tmp_path, monkeypatch):
    """The whole pipeline (training stood in by the smoke run's weights) with a stand-in
    predictor that returns, in each
    tile, every truth box whose centre the tile shows (in tile pixels; boxes in overlaps come
    from several tiles): predictions land in the original frame and merge without duplicates
    when the report says AP 1.0, no false positive, for every group."""
    syn, real = data
    cfg = Sim2RealConfig(arms=parse_arms([f"p={syn}"]), real=real, out=tmp_path / "perfect", epochs=1,
                         imgsz=128, device="cpu", workers=0, batch=4, tile=96, overlap=48,
                         ignore_border={"same": 2.0})
    _, _, gsds, items, plans, _ = pipeline.check_inputs(cfg)
    plan = plans[gsds["p"]]
    assert any(r.scale != (1.0, 1.0) for r in plan) and any(len(r.tiles) > 1 for r in plan)

    class Perfect:
        def __init__(self, *a, **k):
            self.queue = iter(plan)

        def __call__(self, arrays, batch=8):
            r = next(self.queue)
            assert [a.shape[:2] for a in arrays] == [(h, w) for (_, _, w, h) in r.tiles]
            scaled = r.labels.polygons_xy_px * np.asarray(r.scale)
            c = scaled.mean(1)
            out = []
            for (x, y, w, h) in r.tiles:
                ins = (c[:, 0] >= x) & (c[:, 0] < x + w) & (c[:, 1] >= y) & (c[:, 1] < y + h)
                out.append((scaled[ins] - (x, y), np.full(int(ins.sum()), 0.9),
                            [r.labels.classes[i] for i in np.nonzero(ins)[0]]))
                seen.append(int(ins.sum()))
            return out

    seen: list[int] = []
    rep0 = json.loads((smoke[0] / "report.json").read_text())
    weights = smoke[0] / rep0["arms"][0]["weights"]

    def trained(data_yaml, run_dir, **kw):
        (run_dir / "weights").mkdir(parents=True)
        shutil.copyfile(weights, run_dir / "weights" / "best.pt")
        return ultra.TrainResult(run_dir / "weights" / "best.pt", 1, 0.1, 0.0, 0.0)

    monkeypatch.setattr(ultra, "train", trained)
    monkeypatch.setattr(ultra, "Predictor", Perfect)
    rep = pipeline.run_sim2real(cfg)
    a = rep["arms"][0]
    assert sum(seen) > sum(len(r.labels) for r in plan), "no box was seen by two tiles"
    assert a["real_ap50"] == pytest.approx(1.0)
    assert a["real"]["fp"] == 0 and a["real"]["tp"] == a["real"]["n_gt"] > 0
    for g in ("same", "coarse"):
        assert a["real"]["per_group"][g]["ap50"] == pytest.approx(1.0)


@pytest.mark.skipif("torch" in sys.modules and __import__("torch").cuda.is_available(),
                    reason="a CUDA device is present")
def test_cuda_device_where_there_is_none(data, tmp_path):
    syn, real = data
    out = tmp_path / "cuda"
    r = subprocess.run([sys.executable, "-m", "aerial_synth.cli", "sim2real", "--synthetic", str(syn),
                        "--real", str(real), "--out", str(out), "--device", "0", "--epochs", "1"],
                       capture_output=True, text=True, timeout=300, env=dict(os.environ, PYTHONPATH=str(REPO)),
                       cwd=Path(REPO))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--device 0: no CUDA device here" in lines[0]
    assert not out.exists() and not list(tmp_path.glob(".cuda*"))
