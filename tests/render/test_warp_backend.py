"""The ``warp`` render backend on the CPU: the whole frame from its own ray casts, agreeing
with the ``raycast`` backend within :data:`aerial_synth.render.agreement.TOLERANCES`.

warp-lang is in the test lock (the ``[gpu]`` extra), so ``make test`` runs these; an
environment without it skips this module, saying so (``-ra``)."""

import sys

import numpy as np
import pytest

pytest.importorskip("warp", reason="the [gpu] extra (warp-lang) is not installed; make test "
                    "installs it from the test lock")

from aerial_synth.camera import Camera, CameraConfig  # noqa: E402
from aerial_synth.errors import ConfigError, RenderError  # noqa: E402
from aerial_synth.render import RenderConfig, backends, frame, render_frame  # noqa: E402
from aerial_synth.render.agreement import SWEEP_PAIRS, TOLERANCES, compare_frames, sweep  # noqa: E402
from aerial_synth.render.backends import warp as wb  # noqa: E402
from aerial_synth.scene.raycast import VEHICLES_ONLY, RayScene  # noqa: E402

from .worlds import MIXED_SPECS, make_placement, make_scene, make_world  # noqa: E402


def _cams(size=256):
    cfg = CameraConfig(width_px=size, height_px=size, gsd_m=0.12)
    return [Camera.look_at_ground(cfg, (1.0, 1.0, 0.0), yaw_deg=20.0, tilt_deg=0.0),
            Camera.look_at_ground(cfg, (3.0, 0.0, 0.0), yaw_deg=-35.0, tilt_deg=14.0)]


@pytest.fixture(scope="module")
def mixed():
    return make_world(MIXED_SPECS, crown_at=(8.5, -1.0))


@pytest.fixture(params=["host", "device"])
def shade_where(request, monkeypatch):
    """The warp backend's per-pixel stages: the numba ones on the host, or its own Warp
    kernels (what a CUDA device runs), here on the CPU."""
    monkeypatch.setattr(wb, "SHADE", request.param)
    return request.param


@pytest.mark.parametrize("preset", ["fast", "full"])
def test_agrees_with_raycast_at_256px(mixed, preset, shade_where):
    rs, pl = mixed
    total = None
    for k, cam in enumerate(_cams()):
        a = render_frame(rs, cam, pl, np.random.default_rng(k), RenderConfig.preset(preset))
        b = render_frame(rs, cam, pl, np.random.default_rng(k),
                         RenderConfig.preset(preset, backend="warp"))
        got = compare_frames(a, b, cam, pl, f"mixed/{preset}/{k}")
        if total is None:
            total = got
        else:
            total.add(got)
        # the same factors drawn (the metered exposure follows the pixels), the same vehicles
        metered = ("exposure_gain", "tone_power")
        assert {k: v for k, v in a.factors.items() if k not in metered} == {
            k: v for k, v in b.factors.items() if k not in metered}
        assert abs(a.factors["exposure_gain"] / b.factors["exposure_gain"] - 1) < 0.01
        assert sorted(a.visibility) == sorted(b.visibility)
    assert total.vehicles >= 10  # the test means something: most vehicles in view twice
    assert total.failures() == [], total.summary()


@pytest.mark.parametrize("overrides", [
    {"wet_probability": 1.0, "wet": (0.6, 1.0)},  # wet roads: mirror rays, puddles
    {"overcast_probability": 1.0, "grayscale_probability": 1.0},  # soft shadows, panchromatic
    {"randomise": "textures", "exposure_mode": "fixed", "haze": (0.2, 0.3)},
    {"shadow_edges": "nearest", "texture": False, "soft_shadows": False},  # the fast preset's
    {"shadow_edges": "nearest", "overcast_probability": 1.0, "shadow_step": 3},  # blurred
])
def test_device_shading_covers_every_factor(mixed, overrides, monkeypatch):
    from aerial_synth.render.backends import _warp_device

    monkeypatch.setattr(wb, "SHADE", "device")
    calls = []
    real = _warp_device.shade_on_device
    monkeypatch.setattr(_warp_device, "shade_on_device",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    rs, pl = mixed
    cam = _cams(160)[1]
    total = None
    for seed in (1, 2):
        a = render_frame(rs, cam, pl, np.random.default_rng(seed),
                         RenderConfig.preset("full", **overrides))
        b = render_frame(rs, cam, pl, np.random.default_rng(seed),
                         RenderConfig.preset("full", backend="warp", **overrides))
        got = compare_frames(a, b, cam, pl)
        total = got if total is None else (total.add(got) or total)
        assert a.rgb.std() > 3  # an image, not a flat field
    assert total.failures() == [], total.summary()
    assert total.rgb_mean_abs < 0.1  # the same model: almost every pixel identical
    assert len(calls) == 2  # the device kernels ran


def test_labels_come_from_the_backends_own_buffers(mixed, monkeypatch):
    rs, pl = mixed
    cam = _cams(128)[1]

    def no_raycast(*a, **k):
        raise AssertionError("the warp backend must not use the ray-cast buffers")

    monkeypatch.setattr(frame, "cast_buffers", no_raycast)
    fr = render_frame(rs, cam, pl, np.random.default_rng(1),
                      RenderConfig.preset("fast", backend="warp"))
    ids, counts = np.unique(fr.instance[fr.instance > 0], return_counts=True)
    assert len(ids) >= 4
    for i, n in zip(ids.tolist(), counts.tolist()):
        assert fr.visibility[i].visible_px == n
    assert set(fr.device_buffers) == {"instance", "semantic", "depth"}
    assert np.array_equal(fr.device_buffers["instance"].numpy(), fr.instance)
    assert np.array_equal(fr.device_buffers["depth"].numpy(), fr.depth)
    # semantic ids and depth are those of a hit: vehicles where the instance says so
    assert np.all(fr.semantic[fr.instance > 0] == fr.semantic[fr.instance > 0][0])
    assert np.all((fr.depth > 0) == (fr.semantic > 0))


def test_secondary_rays_answer_as_the_rayscene(mixed):
    rs, _ = mixed
    ws = wb.scene_for(rs, "cpu")
    rng = np.random.default_rng(3)
    o = np.column_stack([rng.uniform(-20, 20, 4000), rng.uniform(-10, 10, 4000),
                         rng.uniform(0.3, 30, 4000)])
    d = rng.normal(size=(4000, 3))
    d[:, 2] = -np.abs(d[:, 2]) - 0.2  # mostly downwards: most rays hit something
    rays = np.hstack([o, d]).astype(np.float32)
    for ign in ((), ("tree",), ("vehicle",), VEHICLES_ONLY):
        a, b = rs.cast_rays(rays, ignore=ign), ws.cast_rays(rays, ignore=ign)
        hit = a.face >= 0
        assert 0.01 < hit.mean() < 1.0
        assert np.mean(hit == (b.face >= 0)) > 0.999, ign
        # the same face, or a tie between coplanar faces (a box's floor on the ground)
        same = (a.face == b.face) | np.isclose(a.t, b.t, rtol=1e-5, atol=1e-5)
        assert np.mean(same) > 0.999, ign
        assert np.mean(a.face == b.face) > 0.99, ign
        for tfar in (np.inf, 2.0):
            occ_a = rs.test_occlusions(rays, ignore=ign, tfar=tfar)
            occ_b = ws.test_occlusions(rays, ignore=ign, tfar=tfar)
            assert np.mean(occ_a == occ_b) > 0.999, (ign, tfar)
    assert ws.cast_rays(np.zeros((0, 6), np.float32)).face.shape == (0,)


def test_vehicles_refit_when_they_move_in_one_rayscene_else_rebuilt():
    from aerial_synth.render.world import add_placement

    scene = make_scene()
    specs = [(1, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5), (2, 8.0, 2.0, 3.0, 4.2, 1.8, 1.45)]
    moved = [(i, x + 3.0, y, h + 0.2, ln, wd, ht) for i, x, y, h, ln, wd, ht in specs]
    cam = _cams(128)[0]
    cfg = RenderConfig.preset("fast", backend="warp")
    before = dict(wb.STATS)
    frames = []
    rs = RayScene(scene)
    # one RayScene: its vehicles, then the same ones moved (refit), then fewer (rebuild);
    # then a new RayScene (an export's next group) with the same triangles: rebuilt too
    for k, sp in enumerate((specs, moved, [specs[0]], moved)):
        if k == 3:
            rs = RayScene(scene)
        rs.clear_vehicles()
        pl = make_placement(sp)
        add_placement(rs, pl, simple_boxes=True)
        fr = render_frame(rs, cam, pl, np.random.default_rng(0), cfg)
        ref = render_frame(rs, cam, pl, np.random.default_rng(0), RenderConfig.preset("fast"))
        assert np.mean(fr.instance == ref.instance) > 0.995
        frames.append(fr)
    assert wb.STATS["refit"] - before["refit"] == 1
    assert wb.STATS["rebuild"] - before["rebuild"] == 3
    assert not np.array_equal(frames[0].instance, frames[1].instance)  # they did move
    assert set(np.unique(frames[2].instance)) == {0, 1}
    assert np.array_equal(frames[3].instance, frames[1].instance)  # refit == rebuild here


def test_device_and_install_errors_are_one_line(monkeypatch):
    import warp

    with pytest.raises(ConfigError, match=r"expected cpu, cuda or cuda:N .*'gpu'"):
        RenderConfig(backend="warp", device="gpu")
    assert wb.resolve_device("cpu") == "cpu"
    n = warp.get_cuda_device_count() if warp.is_cuda_available() else 0
    if n == 0:
        with pytest.raises(RenderError, match=r"^--device cuda: no CUDA device here"):
            backends.get("warp").check("cuda")
    with pytest.raises(RenderError, match=rf"^--device cuda:{n + 3}: no (such CUDA device|CUDA)"):
        backends.get("warp").check(f"cuda:{n + 3}")
    monkeypatch.setitem(sys.modules, "warp", None)  # as if the extra were not installed
    monkeypatch.setattr(wb, "_READY", [])
    with pytest.raises(RenderError, match=r"^--backend warp: NVIDIA Warp \(warp-lang\) is not "
                       r"installed; install the \[gpu\] extra"):
        backends.get("warp").check("cpu")


def test_empty_scene_and_no_vehicles():
    from aerial_synth.scene.model import Scene

    cam = _cams(32)[0]
    for rs in (RayScene(Scene("empty", [])), RayScene(make_scene())):
        fr = render_frame(rs, cam, None, np.random.default_rng(0),
                          RenderConfig.preset("fast", backend="warp"))
        ref = render_frame(rs, cam, None, np.random.default_rng(0), RenderConfig.preset("fast"))
        assert fr.visibility == {} and not fr.instance.any()
        assert np.array_equal(fr.semantic, ref.semantic)


@pytest.mark.slow
def test_agreement_sweep_over_bundled_scenes(shade_where):
    """scenes x scenarios x both presets at 256 px, the per-pixel stages on the host and on
    the device (tools/warp_agreement.py prints it)."""
    got = sweep(SWEEP_PAIRS, frames=2)
    assert got.vehicles >= 50
    assert got.failures() == [], got.summary()
    assert TOLERANCES["instance_equal"] >= 0.995 and TOLERANCES["boxes_matched"] >= 0.99


def _no_cuda() -> bool:
    import warp

    return not (warp.is_cuda_available() and warp.get_cuda_device_count() > 0)


@pytest.mark.parametrize("command", ["render", "export"])
@pytest.mark.parametrize("extra, needle", [
    (["--backend", "warp", "--device", "gpu"], "expected cpu, cuda or cuda:n"),
    (["--backend", "warp", "--device", "cuda:999"], "--device cuda:999: no "),
    (["--backend", "vulkan"], "--backend"),
    (["--device", "cuda"], "--backend raycast runs on the cpu only"),
])
def test_cli_bad_device_exits_2_with_one_line(command, extra, needle, tmp_path, capsys):
    from aerial_synth.cli import main

    out = tmp_path / "out"
    rc = main([command, "--scene", "city_park", "--out", str(out), *extra])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and needle in lines[0].lower(), err
    assert "Traceback" not in err and not out.exists()


@pytest.mark.skipif(not _no_cuda(), reason="this machine has CUDA: --device cuda is valid here")
def test_cli_cuda_without_cuda_exits_2(tmp_path, capsys):
    from aerial_synth.cli import main

    out = tmp_path / "out"
    rc = main(["export", "--scene", "city_park", "--out", str(out), "--backend", "warp",
               "--device", "cuda"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "--device cuda: no CUDA device here" in err, err
    assert not out.exists()


def test_cli_warp_without_the_extra_exits_2(tmp_path):
    """A checkout without warp-lang: a 'warp' package that cannot be imported shadows it."""
    import os
    import subprocess

    from ..helpers import REPO

    fake = tmp_path / "site" / "warp"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('no warp here')\n")
    env = dict(os.environ, PYTHONPATH=f"{fake.parent}{os.pathsep}{REPO}")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "aerial_synth.cli", "render", "--scene",
                        "city_park", "--out", str(out), "--backend", "warp"],
                       capture_output=True, text=True, timeout=120, env=env)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "--backend warp: NVIDIA Warp (warp-lang) is not installed" in lines[0]
    assert "[gpu]" in lines[0] and not out.exists()


def test_export_with_warp_gives_the_same_bytes_with_any_worker_count(tmp_path):
    """export --backend warp: a small dataset (two placement groups of box vehicles: the
    same triangles), the same bytes with one worker and with two."""
    from aerial_synth.cli import main

    args = ["export", "--scene", "city_park", "--images", "4", "--images-per-placement", "2",
            "--width", "128", "--height", "128", "--backend", "warp", "--no-progress",
            "--simple-vehicles"]
    assert main([*args, "--workers", "1", "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--workers", "2", "--out", str(tmp_path / "b")]) == 0
    from ..helpers import tree_bytes

    a, b = tree_bytes(tmp_path / "a"), tree_bytes(tmp_path / "b")
    assert a == b and any(k.endswith(".png") for k in a)
    import json

    man = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert man["parameters"]["backend"] == "warp"


def test_a_warp_scene_lives_as_long_as_its_rayscene():
    import gc
    import weakref

    rs, pl = make_world([(1, 0.0, 0.0, 0.0, 4.5, 1.8, 1.5)])
    cam = _cams(32)[0]
    render_frame(rs, cam, pl, np.random.default_rng(0), RenderConfig.preset("fast", backend="warp"))
    ws = wb.scene_for(rs, "cpu")
    assert wb.scene_for(rs, "cpu") is ws and wb.scene_for(ws, "cpu") is ws
    ref = weakref.ref(rs)
    del rs, ws
    gc.collect()
    assert ref() is None  # no cache of the backend keeps a placement group's RayScene alive


def test_frames_go_to_torch_without_a_copy(mixed):
    torch = pytest.importorskip("torch", reason="torch is not installed (the [train] extra)")
    rs, pl = mixed
    fr = render_frame(rs, _cams(64)[0], pl, np.random.default_rng(0),
                      RenderConfig.preset("fast", backend="warp"))
    t = wb.to_torch(fr)
    assert set(t) == {"instance", "semantic", "depth", "rgb"}
    assert t["instance"].dtype == torch.uint32 and t["depth"].dtype == torch.float32
    assert np.array_equal(t["depth"].numpy(), fr.depth)
    assert np.array_equal(t["semantic"].numpy(), fr.semantic)
    # the same memory as Warp's array: a write through torch shows in Warp's array
    t["depth"][0, 0] = -7.0
    assert fr.device_buffers["depth"].numpy()[0, 0] == -7.0
    assert t["rgb"].data_ptr() == fr.rgb.__array_interface__["data"][0]
    with pytest.raises(RenderError, match="to_torch: expected a frame rendered by --backend warp"):
        wb.to_torch(render_frame(rs, _cams(32)[0], pl, np.random.default_rng(0),
                                 RenderConfig.preset("fast")))


def test_device_shading_follows_vehicle_changes_in_one_rayscene(monkeypatch):
    """Vehicles replaced in the same RayScene (render --placement-per-image): the device
    tables (materials, albedo) follow, so the new vehicles are shaded with their own."""
    from aerial_synth.render.world import add_placement

    monkeypatch.setattr(wb, "SHADE", "device")
    rs, pl = make_world([(1, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5)])
    cam = _cams(96)[0]
    cfg = RenderConfig.preset("fast", backend="warp", jpeg_probability=0.0)
    render_frame(rs, cam, pl, np.random.default_rng(0), cfg)
    pl2 = make_placement([(5, 2.0, 1.0, 0.5, 9.0, 2.5, 3.2), (6, -6.0, -2.0, 0.0, 4.2, 1.8, 1.4)])
    rs.clear_vehicles()
    add_placement(rs, pl2, simple_boxes=True)
    b = render_frame(rs, cam, pl2, np.random.default_rng(1), cfg)
    a = render_frame(rs, cam, pl2, np.random.default_rng(1), RenderConfig.preset(
        "fast", jpeg_probability=0.0))
    assert set(np.unique(b.instance)) == {0, 5, 6}
    tabs = wb.scene_for(rs, "cpu").__dict__["_shade_tables"]
    assert tabs["face_mat"].shape[0] == len(rs.face_material)  # the new vehicles' faces
    assert np.array_equal(tabs["face_alb"].numpy(), rs.face_albedo)
    got = compare_frames(a, b, cam, pl2)
    assert got.failures() == [] and got.rgb_mean_abs < 0.05, got.summary()
