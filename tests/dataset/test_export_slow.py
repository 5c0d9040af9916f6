"""End-to-end export over a real bundled scene (slow: run with -m slow)."""

import numpy as np
import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.formats import dota

from .conftest import tree_bytes


@pytest.mark.slow
def test_city_park_jam_all_formats_two_workers(tmp_path):
    cfg = ExportConfig(scene="city_park", scenario="jam", images=4, formats="dota,eagle,yolo-obb,coco",
                       images_per_placement=2,
                       camera=CameraConfig(width_px=512, height_px=512), seed=1)
    r1 = export_dataset(cfg, tmp_path / "a", workers=1, progress=False)
    export_dataset(cfg, tmp_path / "b", workers=2, progress=False)
    a, b = tree_bytes(tmp_path / "a"), tree_bytes(tmp_path / "b")
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []
    assert r1.summary["vehicles_kept"] > 0
    lab = dota.read(tmp_path / "a" / "dota" / "train" / "labelTxt" / "000000.txt")
    assert lab.gsd_m == pytest.approx(0.12, rel=0.1) and np.isfinite(lab.gsd_m)


@pytest.mark.slow
def test_ctrl_c_with_workers_one_line_and_resumable(tiny_scene, tmp_path):
    """SIGINT to an export with --workers 2: one line, exit 130, no worker traceback, the
    partial build kept for --resume, --out not created."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from .conftest import REPO

    out = tmp_path / "ds"
    part = tmp_path / ".ds.aerial-synth-partial"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    p = subprocess.Popen([sys.executable, "-m", "aerial_synth.cli", "export", "--scene", tiny_scene,
                          "--images", "6", "--images-per-placement", "2", "--size", "128", "--vehicles", "8",
                          "--simple-vehicles", "--workers", "2", "--no-progress", "--out", str(out)],
                         env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # even under nohup
    t0 = time.time()
    while not list((part / "meta").glob("*.json")) and p.poll() is None and time.time() - t0 < 300:
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130 and err.decode().strip() == "aerial-synth: interrupted"
    assert not out.exists() and (part / "manifest.json").is_file()
