"""The compiled per-pixel kernels against plain numpy references, and thread independence."""

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render import RenderConfig, render_frame
from aerial_synth.render import _kernels as K
from aerial_synth.render import _vis_kernels as V
from aerial_synth.render.shading import _normal_quantiles
from aerial_synth.render.visibility import _box_exit_t, _box_frames

from .worlds import make_placement, make_world, with_threads

SMALL = CameraConfig(width_px=256, height_px=256, gsd_m=0.12)


def test_noise_is_standard_normal_and_thread_independent():
    base = np.full((300, 400, 3), 128, np.uint8)

    def noisy(seed, threads):
        img = base.copy()
        with_threads(threads, lambda: K.add_noise(img, np.uint64(seed), np.float32(20.0),
                                                   np.float32(0.0), _normal_quantiles()))
        return img

    a, b = noisy(7, 1), noisy(7, 2)
    assert a.tobytes() == b.tobytes()
    d = a.astype(np.float64) - 128
    assert (d[..., 0] == d[..., 2]).all()  # luminance noise: same offset in every channel
    # trunc(20 z): mean 0, sd just under 20 (truncation towards zero removes ~0.5)
    assert abs(d.mean()) < 0.2 and 19.0 < d[..., 0].std() < 20.0
    # no correlation between neighbouring pixels
    x = d[..., 0]
    assert abs(np.corrcoef(x[:, 1:].ravel(), x[:, :-1].ravel())[0, 1]) < 0.02
    assert noisy(8, 2).tobytes() != a.tobytes()
    # saturates instead of wrapping
    img = np.full((64, 64, 3), 250, np.uint8)
    K.add_noise(img, np.uint64(1), np.float32(50.0), np.float32(0.0), _normal_quantiles())
    assert img.max() == 255 and (img >= 250 - 50 * 5).all()


def test_normal_quantiles_are_symmetric_standard_normal():
    q = _normal_quantiles().astype(np.float64)
    assert q.shape == (65536,) and np.allclose(q, -q[::-1], atol=1e-5)
    assert abs(q.mean()) < 1e-6 and q.std() == pytest.approx(1.0, abs=2e-3)


def test_instance_boxes_match_numpy():
    rng = np.random.default_rng(0)
    inst = np.zeros((120, 90), np.uint32)
    for vid in range(1, 30):
        r, c = rng.integers(0, 110), rng.integers(0, 80)
        inst[r : r + rng.integers(1, 10), c : c + rng.integers(1, 10)] = vid
    inst[5, 5] = 1000  # an id not asked for is skipped
    inst[60:63, 2:9] = 3_000_000_000  # a tiled world's id: memory follows the ids asked for
    ids = np.array(list(range(1, 40)) + [3_000_000_000, 4_000_000_000], np.uint32)
    counts, boxes = V.instance_boxes(inst, ids)
    assert counts.shape == (len(ids),) and boxes.shape == (len(ids), 4)
    for j, vid in enumerate(ids):
        rows, cols = np.nonzero(inst == vid)
        assert counts[j] == len(rows)
        if len(rows):
            assert tuple(boxes[j]) == (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1)
        else:
            assert tuple(boxes[j]) == (90, 120, 0, 0)
    assert counts[-2] == 21 and counts[-1] == 0


def test_box_union_pixels_match_a_canvas():
    rng = np.random.default_rng(1)
    x0 = rng.integers(-20, 100, 12)
    y0 = rng.integers(-20, 100, 12)
    x1 = x0 + rng.integers(1, 40, 12)
    y1 = y0 + rng.integers(1, 40, 12)
    rows, cols, multi = V.box_union_pixels(x0, y0, x1, y1)
    cover = np.zeros((200, 200), int)
    for a, b, c, d in zip(x0, y0, x1, y1):
        cover[b + 50 : d + 50, a + 50 : c + 50] += 1
    rr, cc = np.nonzero(cover)
    assert np.array_equal(rows, rr - 50) and np.array_equal(cols, cc - 50)
    assert np.array_equal(multi, cover[rr, cc] > 1)


def test_box_exit_parameter():
    # a 4 x 2 x 1.5 m box at the origin turned by 90 degrees: x in [-1, 1], y in [-2, 2]
    pl = make_placement([(1, 0.0, 0.0, np.pi / 2, 4.0, 2.0, 1.5)])
    fr = _box_frames(pl.vehicles)
    rays = np.array([
        [0.5, 1.5, 10.0, 0.0, 0.0, -1.0],  # straight down: leaves through the floor z = 0
        [-5.0, 0.0, 0.5, 1.0, 0.0, 0.0],  # along +x: leaves at x = 1
        [0.0, -5.0, 0.5, 0.0, 2.0, 0.0],  # along +y, direction of length 2: y = 2 at t 3.5
        [5.0, 5.0, 10.0, 0.0, 0.0, -1.0],  # misses the box
    ], np.float32)
    t = _box_exit_t(rays, np.repeat(fr, 4, axis=0))
    assert t[:3] == pytest.approx([10.0, 6.0, 3.5], abs=1e-5)
    assert t[3] == -np.inf


@pytest.mark.parametrize("tilt_axis", [180.0, 270.0])
def test_amodal_of_a_row_of_vehicles_seen_obliquely(tilt_axis):
    # five cars nose to tail and a tall truck beside them, seen 15 degrees off nadir: rays
    # cross several vehicles, and each one's amodal silhouette must equal the one it has
    # alone (peeling restarts behind each vehicle's box)
    spec = [(i + 1, 4.7 * i, 0.0, 0.0, 4.5, 1.8, 1.5) for i in range(5)]
    spec.append((9, 9.4, 2.4, 0.0, 9.0, 2.5, 4.0))
    cam = Camera.look_at_ground(SMALL, (3.0, 0.0, 0.0), tilt_deg=15.0, tilt_axis_deg=tilt_axis)
    cfg = RenderConfig(jpeg_probability=0.0)
    rs, pl = make_world(spec, building=False)
    f = render_frame(rs, cam, pl, np.random.default_rng(0), cfg)
    assert min(v.visible_fraction for v in f.visibility.values()) < 0.97
    for s in spec:
        rs1, pl1 = make_world([s], building=False)
        one = render_frame(rs1, cam, pl1, np.random.default_rng(0), cfg)
        m, o = f.amodal_mask(s[0])
        m1, o1 = one.amodal_mask(s[0])
        assert o == o1 and np.array_equal(m, m1), s[0]
        assert f.visibility[s[0]].amodal_px_full == one.visibility[s[0]].amodal_px_full


def test_frame_is_identical_for_any_thread_count():
    spec = [(1, 0.0, 0.0, 0.3, 4.5, 1.8, 1.5), (2, 6.0, -2.0, 0.0, 9.0, 2.5, 3.5)]
    rs, pl = make_world(spec, crown_at=(3.0, 3.0))
    cam = Camera.look_at_ground(SMALL, (2.0, 0.0, 0.0), yaw_deg=20.0, tilt_deg=8.0)
    cfg = RenderConfig(jpeg_probability=0.0, wet_probability=1.0, overcast_probability=0.0)
    a = with_threads(1, lambda: render_frame(rs, cam, pl, np.random.default_rng(3), cfg))
    b = with_threads(2, lambda: render_frame(rs, cam, pl, np.random.default_rng(3), cfg))
    for name in ("instance", "semantic", "depth", "rgb"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name


def test_block_shadow_sampling_matches_one_ray_per_pixel():
    # trees and a house cast shadows on road, grass and vehicles; one shadow ray per 2 x 2
    # block (plus object edges) must reproduce the per-pixel image almost everywhere
    from aerial_synth.render.buffers import cast_buffers
    from aerial_synth.render.config import sample_factors
    from aerial_synth.render.shading import shade

    spec = [(1, 22.0, 0.0, 0.3, 4.5, 1.8, 1.5), (2, 30.0, -2.0, 0.0, 9.0, 2.5, 3.5)]
    rs, pl = make_world(spec, crown_at=(26.0, 3.0))
    cam = Camera.look_at_ground(SMALL, (26.0, 6.0, 0.0), yaw_deg=30.0, tilt_deg=6.0)
    cfg = RenderConfig(sun_azimuth_deg=(200, 200), sun_elevation_deg=(25, 25), haze=(0, 0),
                       overcast_probability=0, wet_probability=0, jpeg_probability=0,
                       noise_sigma=(0, 0), blur_sigma_px=(0, 0), vignetting=(0, 0),
                       exposure_mode="fixed", soft_shadows=False, shot_noise=(0, 0),
                       grayscale_probability=0)
    factors = sample_factors(cfg, np.random.default_rng(0))
    buf = cast_buffers(rs, cam)
    one = shade(rs, cam, buf, factors, np.random.default_rng(0), shadow_step=1).astype(int)
    two = shade(rs, cam, buf, factors, np.random.default_rng(0), shadow_step=2).astype(int)
    off = shade(rs, cam, buf, {**factors, "shadows": False}, np.random.default_rng(0))
    shadowed = (off.astype(int) - one).max(axis=2) > 20
    assert shadowed.mean() > 0.05  # the scene really has shadows
    differ = np.abs(one - two).max(axis=2) > 20
    assert differ.mean() < 0.01
    # the fast preset's edges: object-edge pixels copy a same-surface corner sample
    for step, limit in ((2, 0.015), (4, 0.03)):
        near = shade(rs, cam, buf, {**factors, "shadow_edges": "nearest"},
                     np.random.default_rng(0), shadow_step=step).astype(int)
        assert (np.abs(one - near).max(axis=2) > 20).mean() < limit
    # where the block sampling differs, it is at a shadow edge inside one surface
    edge = np.zeros_like(shadowed)
    edge[1:-1, 1:-1] = (shadowed[1:-1, 1:-1] != shadowed[:-2, 1:-1]) | (
        shadowed[1:-1, 1:-1] != shadowed[2:, 1:-1]) | (
        shadowed[1:-1, 1:-1] != shadowed[1:-1, :-2]) | (shadowed[1:-1, 1:-1] != shadowed[1:-1, 2:])
    near_edge = np.zeros_like(edge)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_edge |= np.roll(np.roll(edge, dy, 0), dx, 1)
    assert (differ & ~near_edge).sum() <= 0.001 * differ.size


def test_all_pixel_rays_equal_per_pixel_rays_bit_for_bit():
    # the primary rays (compiled, separable) and the amodal rays (pixel_rays(rows, cols))
    # must be the same bits, or visible and amodal masks could disagree on edge pixels
    cfg = CameraConfig(width_px=301, height_px=177, gsd_m=0.1)
    cam = Camera.look_at_ground(cfg, (12.3, -4.5, 1.0), yaw_deg=123.0, tilt_deg=-11.0,
                                tilt_axis_deg=33.0)
    rows = np.repeat(np.arange(177), 301)
    cols = np.tile(np.arange(301), 177)
    a = cam.pixel_rays()
    b = cam.pixel_rays(rows, cols)
    assert a.shape == (301 * 177, 6) and a.tobytes() == b.tobytes()


def _nearest_reference(h, w, step, face, ndl, semantic, depth, lit_rays):
    """Straightforward formulation of ``shadow_edges="nearest"``: which pixels cast (own)
    and the sun visibility every pixel ends with, given each pixel's own ray result
    ``lit_rays`` (n,) (as if every pixel had cast one)."""
    own = np.zeros(h * w, bool)
    lit = np.ones(h * w, np.float32)
    for r in range(h):
        for c in range(w):
            i = r * w + c
            if face[i] < 0:
                continue
            r0, c0 = r - r % step, c - c % step
            if (r, c) == (r0, c0):
                own[i] = True
                lit[i] = lit_rays[i]
                continue
            if ndl[i] <= 0:
                continue
            for rr, cc in ((r0, c0), (r0, c0 + step), (r0 + step, c0), (r0 + step, c0 + step)):
                j = rr * w + cc
                if rr < h and cc < w and face[j] >= 0 and semantic[j] == semantic[i] and abs(
                        depth[i] - depth[j]) <= np.float32(0.2):
                    lit[i] = lit_rays[j]
                    break
            else:
                own[i] = True
                lit[i] = lit_rays[i]
    return own, lit


@pytest.mark.parametrize("step", [2, 4])
def test_nearest_shadow_edges_match_a_plain_reference(step):
    from aerial_synth.render import shading
    from aerial_synth.render.buffers import cast_buffers

    spec = [(1, 22.0, 0.0, 0.3, 4.5, 1.8, 1.5), (2, 30.0, -2.0, 0.0, 9.0, 2.5, 3.5)]
    rs, pl = make_world(spec, crown_at=(26.0, 3.0))
    cfg = CameraConfig(width_px=97, height_px=83, gsd_m=0.25)
    cam = Camera.look_at_ground(cfg, (26.0, 3.0, 0.0), yaw_deg=20.0, tilt_deg=8.0)
    buf = cast_buffers(rs, cam)
    h, w, n = buf.height_px, buf.width_px, buf.height_px * buf.width_px
    L = shading.sun_direction(200.0, 30.0).astype(np.float32)
    sem, dep = buf.semantic.reshape(-1), buf.depth.reshape(-1)
    ndl, own, src = np.empty(n, np.float32), np.empty(n, bool), np.empty(n, np.uint8)
    K.surface(h, w, buf.rays, buf.t, buf.face, buf.normal, sem, dep, rs.face_material,
              shading._noise_tiles(0), False, L, shading._FOLIAGE, step, True, ndl, own, src)
    # every pixel's own shadow ray, then what the kernels keep of them
    _, srays = K.gather_shadow_rays(buf.face >= 0, buf.rays, buf.t, buf.normal, L,
                                    np.float32(shading._PEEL), np.zeros((2, 3), np.float32),
                                    np.uint64(0))
    lit_rays = np.ones(n, np.float32)
    lit_rays[buf.face >= 0] = np.where(rs.test_occlusions(srays), 0.0, 1.0)
    ref_own, ref_lit = _nearest_reference(h, w, step, buf.face, ndl, sem, dep, lit_rays)
    np.testing.assert_array_equal(own, ref_own)
    idx = np.flatnonzero(own)
    lit = np.ones(n, np.float32)
    K.spread_shadow_nearest(h, w, step, own, ndl, src, idx, lit_rays[idx], lit)
    np.testing.assert_array_equal(lit, ref_lit)
    # fewer rays than the "cast" edges, which mark a superset of them
    cast_own = np.empty(n, bool)
    K.surface(h, w, buf.rays, buf.t, buf.face, buf.normal, sem, dep, rs.face_material,
              shading._noise_tiles(0), False, L, shading._FOLIAGE, step, False, ndl, cast_own,
              src[:1])
    assert (own <= cast_own).all() and own.sum() < cast_own.sum()
    assert (lit_rays == 0).any() and (lit_rays == 1).any()


@pytest.mark.parametrize("soft", [False, True])
def test_parallel_shadow_gather_equals_a_serial_pass(soft):
    rng = np.random.default_rng(5)
    n = 40_000
    own = rng.random(n) < 0.3
    own[:100] = False
    rays = rng.normal(size=(n, 6)).astype(np.float32)
    t = rng.uniform(1, 100, n).astype(np.float32)
    normal = rng.normal(size=(n, 3)).astype(np.float32)
    light = np.array([0.3, -0.4, 0.866], np.float32)
    disk = (np.array([[0.01, 0.0, -0.003], [0.0, 0.01, 0.004]], np.float32) if soft
            else np.zeros((2, 3), np.float32))
    args = (own, rays, t, normal, light, np.float32(0.02), disk, np.uint64(99))
    idx, out = with_threads(2, lambda: K.gather_shadow_rays(*args))
    np.testing.assert_array_equal(idx, np.flatnonzero(own))
    p = rays[idx, :3] + t[idx, None] * rays[idx, 3:] + np.float32(0.02) * normal[idx]
    np.testing.assert_array_equal(out[:, :3], p)
    if not soft:
        np.testing.assert_array_equal(out[:, 3:], np.broadcast_to(light, (len(idx), 3)))
    else:  # the serial formulation (the kernel's Python body, one chunk after another)
        with np.errstate(over="ignore"):  # the hash wraps around in uint64
            i2, o2 = K.gather_shadow_rays.py_func(own[:3000], *args[1:])
        np.testing.assert_array_equal(i2, idx[idx < 3000])
        np.testing.assert_allclose(o2, out[: len(i2)], rtol=1e-6, atol=1e-7)
        off = np.linalg.norm(out[:, 3:] - light, axis=1)
        assert off.max() <= 0.012 and off.std() > 0.001  # within the disk (|a, b| <= 1)


def test_tone_histogram_equals_numpy():
    # the auto exposure's compiled histogram against np.histogram, values on bin edges too
    from aerial_synth.render._tone import histogram_uniform

    rng = np.random.default_rng(1)
    for trial in range(100):
        a = rng.normal(rng.uniform(-5, 5), rng.uniform(0.01, 3), rng.integers(1, 3000))
        lo, hi = float(a.min()), float(a.max()) + (1e-6 if trial % 2 else 0.0)
        e = np.linspace(lo, hi, 257)
        a = np.concatenate([a, e[rng.integers(0, 257, 50)],
                            [lo, hi, np.nextafter(hi, 1e9), np.nextafter(lo, -1e9)]])
        ref, ref_edges = np.histogram(a, bins=256, range=(lo, hi))
        assert np.array_equal(ref_edges, e)
        assert np.array_equal(histogram_uniform(a, e), ref)


@pytest.mark.parametrize("preset", ["full", "fast"])
def test_visibility_beside_shading_gives_the_same_frame(monkeypatch, preset):
    # render_frame runs visibility in a second thread while shading: the same frame as one
    # stage after the other, and an error in visibility reaches the caller
    from aerial_synth.render.backends import raycast as F

    spec = [(1, 0.0, 0.0, 0.3, 4.5, 1.8, 1.5), (2, 6.0, -2.0, 0.0, 9.0, 2.5, 3.5)]
    rs, pl = make_world(spec, crown_at=(3.0, 3.0))
    cam = Camera.look_at_ground(SMALL, (2.0, 0.0, 0.0), yaw_deg=20.0, tilt_deg=8.0)
    cfg = RenderConfig.preset(preset, jpeg_probability=0.0)
    out = {}
    for overlap in (True, False):
        monkeypatch.setattr(F, "OVERLAP_VISIBILITY", overlap)
        out[overlap] = render_frame(rs, cam, pl, np.random.default_rng(4), cfg)
    a, b = out[True], out[False]
    assert F._thread_safe_kernels()
    for name in ("instance", "semantic", "depth", "rgb"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    assert a.visibility == b.visibility and len(a.visibility) == 2
    assert a.amodal.ids.tobytes() == b.amodal.ids.tobytes()
    assert a.amodal.rows.tobytes() == b.amodal.rows.tobytes()
    assert a.to_meta() == b.to_meta()

    def broken(*args, **kw):
        raise RuntimeError("visibility failed")

    monkeypatch.setattr(F, "OVERLAP_VISIBILITY", True)
    monkeypatch.setattr(F, "compute_visibility", broken)
    with pytest.raises(RuntimeError, match="visibility failed"):
        render_frame(rs, cam, pl, np.random.default_rng(4), cfg)


@pytest.mark.parametrize("step", [1, 3, 4])
def test_shadow_spread_inside_compose_equals_the_spread_pass(monkeypatch, step):
    # unblurred shadows (point sun, no overcast): compose reads the block samples itself;
    # the image must be the one of spread_shadow's pass over the image, byte for byte
    from aerial_synth.render import shading
    from aerial_synth.render.buffers import cast_buffers
    from aerial_synth.render.config import sample_factors

    spec = [(1, 22.0, 0.0, 0.3, 4.5, 1.8, 1.5), (2, 30.0, -2.0, 0.0, 9.0, 2.5, 3.5)]
    rs, pl = make_world(spec, crown_at=(26.0, 3.0))
    cam = Camera.look_at_ground(SMALL, (26.0, 6.0, 0.0), yaw_deg=30.0, tilt_deg=6.0)
    buf = cast_buffers(rs, cam)
    for preset, edges in (("fast", "nearest"), ("fast", "cast"), ("full", "cast")):
        cfg = RenderConfig.preset(preset, soft_shadows=False, overcast_probability=0,
                                  jpeg_probability=0, shadow_step=step,
                                  shadow_edges=edges)
        factors = sample_factors(cfg, np.random.default_rng(3))
        out = {}
        for fused in (True, False):
            monkeypatch.setattr(shading, "_SPREAD_IN_COMPOSE", fused)
            out[fused] = shading.shade(rs, cam, buf, dict(factors))
        assert out[True].tobytes() == out[False].tobytes()


def _spread_ao_reference(h, w, step, low, semantic, depth):
    """Plain per-pixel statement of :func:`K.spread_ao` (no shortcut for all-ones cells)."""
    bh, bw, half = -(-h // step), -(-w // step), step // 2
    out = np.ones(h * w, np.float32)
    f32 = np.float32
    for r in range(h):
        fr = (f32(r) - f32(half)) / f32(step)
        br0 = min(max(int(np.floor(fr)), 0), bh - 1)
        br1 = min(br0 + 1, bh - 1)
        wr = min(max(fr - f32(br0), f32(0)), f32(1))
        for c in range(w):
            i = r * w + c
            fc = (f32(c) - f32(half)) / f32(step)
            bc0 = min(max(int(np.floor(fc)), 0), bw - 1)
            bc1 = min(bc0 + 1, bw - 1)
            wc = min(max(fc - f32(bc0), f32(0)), f32(1))
            acc, wsum = f32(0), f32(0)
            for bri, bci, wq in ((br0, bc0, (f32(1) - wr) * (f32(1) - wc)),
                                 (br0, bc1, (f32(1) - wr) * wc),
                                 (br1, bc0, wr * (f32(1) - wc)), (br1, bc1, wr * wc)):
                v = low[bri * bw + bci]
                si = min(bri * step + half, h - 1) * w + min(bci * step + half, w - 1)
                if (v < 0 or wq <= 0 or semantic[si] != semantic[i]
                        or abs(depth[si] - depth[i]) > f32(0.3) + f32(0.05) * depth[i]):
                    continue
                acc = f32(acc + f32(wq * v))
                wsum = f32(wsum + wq)
            if wsum > 0:
                out[i] = f32(acc / wsum)
            else:
                v = low[(r // step) * bw + c // step]
                out[i] = v if v >= 0 else f32(1)
    return out


@pytest.mark.parametrize("step", [1, 4, 5])
def test_ao_spread_equals_a_plain_reference(step):
    """Bilinear AO between same-surface block samples; most cells are all ones or empty (the
    kernel's shortcut), some hold occluded samples, across label and depth edges."""
    rng = np.random.default_rng(step)
    h, w = 53, 61
    bh, bw = -(-h // step), -(-w // step)
    low = np.ones(bh * bw, np.float32)
    low[rng.random(bh * bw) < 0.15] = -1.0  # no sample (a miss)
    occluded = rng.random(bh * bw) < 0.2
    low[occluded] = rng.random(int(occluded.sum())).astype(np.float32)
    semantic = np.where(np.arange(w)[None, :] < 30, 1, 3).repeat(h, 0).astype(np.uint8).reshape(-1)
    depth = (60.0 + np.where(np.arange(h)[:, None] < 20, -4.0, 0.0)
             + 0.01 * rng.random((h, w))).astype(np.float32).reshape(-1)
    ao = np.full(h * w, -7.0, np.float32)  # every pixel must be written
    K.spread_ao(h, w, step, low, semantic, depth, ao)
    ref = _spread_ao_reference(h, w, step, low, semantic, depth)
    np.testing.assert_array_equal(ao, ref)
    assert (ao == 1).mean() > 0.3 and (ao < 1).mean() > 0.1  # both paths taken
