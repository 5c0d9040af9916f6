"""Smooth shading normals on foliage: interpolated vertex normals, geometry untouched."""

from __future__ import annotations

import numpy as np
import trimesh

from aerial_synth.render.smooth import corner_normals, smooth_shading_normals
from aerial_synth.scene.model import Scene, SceneObject
from aerial_synth.scene.raycast import RayScene


def _scene():
    ball = trimesh.creation.icosphere(subdivisions=0, radius=3.0)  # 20 facets
    crown = SceneObject("crown", "tree", np.asarray(ball.vertices) + (0.0, 0.0, 8.0),
                        np.asarray(ball.faces), material="foliage")
    box = trimesh.creation.box((4.0, 4.0, 2.0))
    roof = SceneObject("house", "building", np.asarray(box.vertices) + (10.0, 0.0, 1.0),
                       np.asarray(box.faces), material="roof")
    return Scene(name="t", objects=[roof, crown])


def _rays(xs, ys):
    X, Y = np.meshgrid(xs, ys)
    n = X.size
    r = np.zeros((n, 6), np.float32)
    r[:, 0], r[:, 1], r[:, 2], r[:, 5] = X.ravel(), Y.ravel(), 50.0, -1.0
    return r


def _cast(rs, rays):
    ans = rs._cast_raw(rays)
    lut, offs = ans["lut"]
    gid, pid = ans["geometry_ids"], ans["primitive_ids"]
    valid = gid < len(offs) - 1
    idx = np.where(valid, offs[np.where(valid, gid, 0)] + np.where(valid, pid, 0), len(lut) - 1)
    face = lut[idx]  # the table's last entry is the miss sentinel -1
    normal = np.array(ans["primitive_normals"], np.float32)
    flip = (normal * rays[:, 3:]).sum(1) > 0
    normal[flip] *= -1
    return face, np.array(ans["primitive_uvs"], np.float32), ans["t_hit"], normal


def test_foliage_normals_follow_the_sphere_and_other_faces_keep_theirs():
    rs = RayScene(_scene())
    rays = _rays(np.linspace(-2.5, 2.5, 41), np.linspace(-2.5, 2.5, 41))
    rays = np.concatenate([rays, _rays(np.linspace(9, 11, 5), np.linspace(-1, 1, 5))])
    face, uv, t, geo = _cast(rs, rays)
    hit = face >= 0
    assert hit.sum() > 1000
    n = geo.copy()
    smooth_shading_normals(rs, face, uv, rays, n)
    # misses have t = inf (inf * a zero direction component is nan): their points are not used
    p = rays[:, :3] + np.where(hit, t, 0.0)[:, None] * rays[:, 3:]
    radial = p - (0.0, 0.0, 8.0)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    crown = hit & (rs.face_material[np.maximum(face, 0)] == 10)  # foliage id
    assert crown.sum() > 1000
    err_geo = np.degrees(np.arccos(np.clip((geo[crown] * radial[crown]).sum(1), -1, 1)))
    err_s = np.degrees(np.arccos(np.clip((n[crown] * radial[crown]).sum(1), -1, 1)))
    # a facet's normal is off the sphere's by up to ~37 deg; the interpolated one far less
    assert np.median(err_s) < 0.5 * np.median(err_geo)
    assert np.percentile(err_s, 95) < np.percentile(err_geo, 95)
    np.testing.assert_allclose(np.linalg.norm(n[crown], axis=1), 1.0, atol=1e-5)
    assert ((n[crown] * rays[crown, 3:]).sum(1) < 0).all()  # still facing the camera
    # non-foliage hits (the roof box) and misses are untouched, bit for bit
    assert np.array_equal(n[~crown], geo[~crown])


def test_corner_table_is_cached_and_covers_only_foliage():
    rs = RayScene(_scene())
    row, corners = corner_normals(rs)
    assert corner_normals(rs)[1] is corners
    n_roof = rs.scene.objects[0].n_triangles
    assert (row[:n_roof] == -1).all() and (row[n_roof:] >= 0).all()
    assert corners.shape == (20, 3, 3)
    np.testing.assert_allclose(np.linalg.norm(corners, axis=2), 1.0, atol=1e-6)


def finish_buffers(rays, t, gid, pid, lut, offs, face_label, face_instance, normal, face,
                   depth, semantic, instance):
    """The straightforward numpy formulation of the fused pass's first half: global face
    (-1 on miss), labels and instance ids (0 on miss), depth (0 on miss), and the normal
    turned to face the camera, in place, with the same float32 operations."""
    g = np.asarray(gid).astype(np.int64)
    valid = g < len(offs) - 1
    face[:] = -1
    face[valid] = lut[offs[g[valid]] + np.asarray(pid)[valid].astype(np.int64)]
    hit = face >= 0
    f = np.maximum(face, 0)
    semantic[:] = np.where(hit, face_label[f], 0).astype(np.uint8)
    instance[:] = np.where(hit, face_instance[f], 0).astype(np.uint32)
    depth[:] = np.where(np.isfinite(t), t, np.float32(0.0))
    d = normal[:, 0] * rays[:, 3] + normal[:, 1] * rays[:, 4] + normal[:, 2] * rays[:, 5]
    normal[d > 0] *= np.float32(-1.0)


def test_fused_finish_pass_equals_finish_then_smooth():
    # cast_buffers' one pass (render/smooth.finish_smooth_buffers) against the two passes it
    # replaces: mapping the hits (finish_buffers above), then smooth_shading_normals; also
    # with no smooth faces at all (an empty corner table)
    from aerial_synth.render.smooth import finish_smooth_buffers

    rs = RayScene(_scene())
    rays = _rays(np.linspace(-4, 12, 97), np.linspace(-4, 4, 53))
    rays[::7, 5] = 1.0  # some rays away from everything: misses
    ans = rs._cast_raw(rays)
    lut, offs = ans["lut"]
    uv = np.array(ans["primitive_uvs"], np.float32)
    n = len(rays)
    for row, corners in (corner_normals(rs), (np.zeros(0, np.int32),
                                              np.zeros((0, 3, 3), np.float32))):
        a = [np.empty(n, np.int64), np.empty(n, np.float32), np.empty(n, np.uint8),
             np.empty(n, np.uint32)]
        b = [x.copy() for x in a]
        na = np.array(ans["primitive_normals"], np.float32)
        nb = na.copy()
        finish_buffers(rays, ans["t_hit"], ans["geometry_ids"], ans["primitive_ids"], lut, offs,
                       rs.face_label, rs.face_instance, na, *a)
        if len(corners):
            smooth_shading_normals(rs, a[0], uv, rays, na)
        finish_smooth_buffers(rays, ans["t_hit"], ans["geometry_ids"], ans["primitive_ids"], uv,
                              lut, offs, rs.face_label, rs.face_instance, row, corners, nb, *b)
        assert (a[0] < 0).any() and (a[0] >= 0).any()
        for x, y in zip(a + [na], b + [nb]):
            assert x.tobytes() == y.tobytes()
