"""A frame too large for the memory available is refused in one line, before anything is
written (render.budget)."""

import pytest

from aerial_synth.errors import ExportError, RenderError
from aerial_synth.render import budget
from aerial_synth.render.budget import FRAME_BYTES_PER_PX, check_frame_memory, frame_bytes


def test_frame_bytes_scale_with_pixels():
    assert frame_bytes(1024, 1024) == FRAME_BYTES_PER_PX * 1024 * 1024
    assert frame_bytes(2048, 1024) == 2 * frame_bytes(1024, 1024)
    assert 100 <= FRAME_BYTES_PER_PX <= 200  # measured 98-112 B/px (see the module)


def test_check_passes_and_fails_at_the_estimate():
    need = frame_bytes(4096, 4096)
    check_frame_memory(4096, 4096, available=need)  # exactly fits
    with pytest.raises(RenderError) as e:
        check_frame_memory(4096, 4096, available=need - 1)
    msg = str(e.value)
    assert "\n" not in msg and "4096 x 4096" in msg and "--width/--height" in msg
    # one frame per worker
    check_frame_memory(4096, 4096, processes=3, available=3 * need)
    with pytest.raises(ExportError, match="3 frames .one per worker.*fewer workers"):
        check_frame_memory(4096, 4096, processes=3, available=3 * need - 1, error=ExportError)


def test_unknown_memory_is_not_refused(monkeypatch):
    monkeypatch.setattr(budget, "available_memory_bytes", lambda: None)
    check_frame_memory(16384, 16384)


def test_available_memory_is_read():
    avail = budget.available_memory_bytes()
    assert avail is None or avail > 0


def test_cgroup_limit_caps_the_reading(monkeypatch):
    from aerial_synth import memory  # where the reading lives (render.budget re-exports it)

    monkeypatch.setattr(memory, "_cgroup_room", lambda: 5 * 2**30)
    avail = budget.available_memory_bytes()
    assert avail is not None and avail <= 5 * 2**30


@pytest.mark.parametrize("cmd", ["render", "export"])
def test_cli_refuses_a_frame_that_cannot_fit(cmd, tmp_path, monkeypatch, capsys):
    """16384 x 16384 px (~30 GB) with 1 GB available: one line, exit 2, nothing written
    (it used to load the scene, write placement.json and be OOM-killed)."""
    from aerial_synth.cli import main

    monkeypatch.setattr(budget, "available_memory_bytes", lambda: 2**30)
    out = tmp_path / "out"
    code = main([cmd, "--scene", "city_park", "--width", "16384", "--height", "16384", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "16384 x 16384" in err and "GB" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_export_counts_one_frame_per_local_worker(tmp_path, monkeypatch):
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    one = frame_bytes(2048, 2048)
    monkeypatch.setattr(budget, "available_memory_bytes", lambda: int(2.5 * one))
    cfg = ExportConfig(scene="city_park", images=4,
                       camera=CameraConfig(width_px=2048, height_px=2048))
    for kw in ({"workers": 3}, {"dask": "local:3"}):
        with pytest.raises(ExportError, match="3 frames"):
            export_dataset(cfg, tmp_path / "ds", progress=False, **kw)
    # 2 images: at most 2 frames at once, whatever the worker count (then it would run;
    # stopped here by a bad scene name to keep the test fast)
    small = ExportConfig(scene="no_such_scene_anywhere", images=2,
                         camera=CameraConfig(width_px=2048, height_px=2048))
    with pytest.raises(Exception) as e:
        export_dataset(small, tmp_path / "ds2", workers=3, progress=False)
    assert "frames" not in str(e.value)
    assert list(tmp_path.iterdir()) == []
