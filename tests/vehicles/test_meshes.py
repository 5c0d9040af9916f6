"""Procedural meshes: size, closed outward parts, a visible front, placement, cache."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from aerial_synth.scene.model import MATERIAL_IDS
from aerial_synth.vehicles import VehicleMesh, build_mesh, load_catalog

CAT = load_catalog()
MODELS = [m.name for m in CAT.models]
#: towed bodies (vehicles/towed.py): no cab, so no windscreen, rear window or headlights
TRAILERS = {"farm_trailer", "boat_trailer", "utility_trailer"}
DRIVEN = [n for n in MODELS if n not in TRAILERS]


def _mesh(name: str, color: str = "red") -> VehicleMesh:
    return build_mesh(CAT.model(name), CAT.color(color))


@pytest.mark.parametrize("name", MODELS)
def test_bounds_match_catalog_size(name):
    m = CAT.model(name)
    mesh = _mesh(name)
    lo, hi = mesh.bounds
    size = hi - lo
    np.testing.assert_allclose(size, m.size_m, rtol=0.02)
    # origin: footprint centre, standing on the ground
    np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=0.02 * m.length_m)
    assert abs(lo[2]) < 1e-9


@pytest.mark.parametrize("name", MODELS)
def test_mesh_arrays_follow_the_contract(name):
    trailer = name in TRAILERS
    mesh = _mesh(name)
    n, m = len(mesh.vertices), len(mesh.faces)
    assert mesh.vertices.dtype == np.float64 and mesh.vertices.shape == (n, 3)
    assert mesh.faces.dtype == np.int64 and mesh.faces.shape == (m, 3)
    assert mesh.face_material.dtype == np.uint8 and mesh.face_material.shape == (m,)
    assert mesh.face_albedo.dtype == np.float32 and mesh.face_albedo.shape == (m, 3)
    assert mesh.faces.min() >= 0 and mesh.faces.max() < n
    assert np.all((mesh.face_albedo >= 0) & (mesh.face_albedo <= 1))
    assert set(np.unique(mesh.face_material)) <= set(MATERIAL_IDS.values())
    assert not mesh.vertices.flags.writeable
    want = ("body", "wheels", "light_rear") if trailer else (
        "body", "greenhouse", "roof", "wheels", "windscreen", "rear_window")
    for part in want:
        assert part in mesh.parts, part
    mats = {k for k, v in MATERIAL_IDS.items() if v in set(mesh.face_material.tolist())}
    assert ({"paint", "tyre", "light_rear"} if trailer else {"paint", "glass", "tyre", "light_front",
                                                             "light_rear"}) <= mats


@pytest.mark.parametrize("name", MODELS)
def test_every_part_is_closed_with_outward_normals(name):
    """Convention: each part is made of closed volumes, CCW seen from outside, so every
    connected piece is watertight, winding-consistent and has a positive signed volume."""
    mesh = _mesh(name)
    for part in mesh.parts:
        v, f = mesh.part_mesh(part)
        tm = trimesh.Trimesh(v, f, process=False)
        pieces = tm.split(only_watertight=False)
        assert len(pieces) >= 1
        for piece in pieces:
            assert piece.is_watertight, (name, part)
            assert piece.is_winding_consistent, (name, part)
            assert piece.volume > 0, (name, part)


@pytest.mark.parametrize("name", sorted(TRAILERS))
def test_trailers_drawbar_forward_lights_behind(name):
    mesh = _mesh(name)
    L = CAT.model(name).length_m
    bar = mesh.vertices[mesh.faces[mesh.part_faces("drawbar")]].reshape(-1, 3)
    assert bar[:, 0].max() > 0.45 * L  # the hitch at the front
    lr = mesh.vertices[mesh.faces[mesh.part_faces("light_rear")]].reshape(-1, 3).mean(axis=0)
    assert lr[0] < -0.4 * L


@pytest.mark.parametrize("name", DRIVEN)
def test_front_differs_from_back(name):
    mesh = _mesh(name)
    ws = mesh.vertices[mesh.faces[mesh.part_faces("windscreen")]].reshape(-1, 3).mean(axis=0)
    rw = mesh.vertices[mesh.faces[mesh.part_faces("rear_window")]].reshape(-1, 3).mean(axis=0)
    assert ws[0] > 0 or name == "tractor"  # a tractor's cab stands over its rear axle
    assert ws[0] > rw[0]
    lf = mesh.vertices[mesh.faces[mesh.part_faces("light_front")]].reshape(-1, 3).mean(axis=0)
    lr = mesh.vertices[mesh.faces[mesh.part_faces("light_rear")]].reshape(-1, 3).mean(axis=0)
    assert lf[0] > 0.3 * CAT.model(name).length_m and lr[0] < -0.3 * CAT.model(name).length_m


@pytest.mark.parametrize("name", ["hatchback", "sedan", "sport_car", "suv"])
def test_cars_have_a_bonnet_longer_than_the_boot(name):
    mesh = _mesh(name)
    L = CAT.model(name).length_m
    ws_x = mesh.vertices[mesh.faces[mesh.part_faces("windscreen")]][..., 0].min()
    rw_x = mesh.vertices[mesh.faces[mesh.part_faces("rear_window")]][..., 0].min()
    bonnet, boot = L / 2 - ws_x, rw_x + L / 2
    assert bonnet > 0.85 and bonnet > boot


def test_trucks_have_cab_and_cargo_box():
    for name in ("box_truck", "box_truck_large"):
        mesh = _mesh(name)
        assert "cargo_box" in mesh.parts
        box = mesh.vertices[mesh.faces[mesh.part_faces("cargo_box")]].reshape(-1, 3)
        roof = mesh.vertices[mesh.faces[mesh.part_faces("roof")]].reshape(-1, 3)
        assert box[:, 0].mean() < 0 < roof[:, 0].mean()  # cab in front, box behind
        assert box[:, 2].max() > roof[:, 2].max()  # the box is taller than the cab
    assert "bed_floor" in _mesh("pickup_truck").parts
    assert "living_box" in _mesh("campervan").parts


def test_colour_goes_to_paint_only():
    red, blue = _mesh("sedan", "red"), _mesh("sedan", "blue")
    paint = red.face_material == MATERIAL_IDS["paint"]
    assert np.allclose(red.face_albedo[paint], CAT.color("red").rgb, atol=1e-6)
    assert np.allclose(blue.face_albedo[paint], CAT.color("blue").rgb, atol=1e-6)
    np.testing.assert_array_equal(red.face_albedo[~paint], blue.face_albedo[~paint])
    np.testing.assert_array_equal(red.vertices, blue.vertices)


def test_build_mesh_is_cached():
    assert _mesh("suv", "white") is _mesh("suv", "white")


def test_to_world_rotates_ccw_and_translates():
    mesh = _mesh("hatchback")
    L = CAT.model("hatchback").length_m
    v, f = mesh.to_world(10.0, -5.0, 2.0, np.pi / 2)  # facing +y (north)
    np.testing.assert_array_equal(f, mesh.faces)
    lo, hi = v.min(axis=0), v.max(axis=0)
    np.testing.assert_allclose([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]], [10, -5, 2],
                               atol=1e-6)
    np.testing.assert_allclose(hi[1] - lo[1], L, rtol=1e-9)
    ws = mesh.part_faces("windscreen")
    assert v[f[ws]].reshape(-1, 3)[:, 1].mean() > -5.0  # the front now points to +y


def test_seen_from_above_every_surface_faces_up():
    """Nadir rays through the project's ray caster hit only upward-facing triangles."""
    from aerial_synth.scene.model import Scene
    from aerial_synth.scene.raycast import RayScene

    rs = RayScene(Scene(name="t", objects=[]))
    names = MODELS
    for k, name in enumerate(names):
        v, f = _mesh(name).to_world(0.0, 10.0 * k, 0.0, 0.3 * k)
        rs.add_vehicle(k + 1, v, f, _mesh(name).face_material, _mesh(name).face_albedo)
    xs, ys = np.meshgrid(np.arange(-5, 5, 0.1), np.arange(-5, 10 * len(names), 0.1))
    rays = np.zeros((xs.size, 6), np.float32)
    rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = xs.ravel(), ys.ravel(), 20.0, -1.0
    hits = rs.cast_rays(rays)
    assert hits.hit.sum() > 1000
    assert np.all(hits.normal[hits.hit, 2] > 0)
