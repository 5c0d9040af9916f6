"""Any-hit tests as a union of a static-only and the vehicles-only Embree scene.

``RayScene.test_occlusions`` answers an ignore-set that keeps the vehicles and has no Embree
scene of its own as (static triangles not ignored) OR (vehicles), so rendering does not build
every vehicle a third time for the shader's crown-gap test (ignore {"tree"}).

- The union gives exactly the answer of a dedicated build of the same ignore-set, on rays
  through and along crowns, vehicles, a building and the ground, with tnear / tfar.
- Static-only builds survive vehicle changes (placement's {"tree"} scene serves the
  renderer) and keep their layout; the union's vehicle half is the amodal stage's scene.
- Rendering frames of an export-like world (traces before vehicles, as placement does)
  builds no Embree scene that holds vehicles but not the trees.
"""

from types import SimpleNamespace

import numpy as np
import pytest

import aerial_synth.scene.raycast as rc
from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render import render_frame
from aerial_synth.render.config import RenderConfig
from aerial_synth.scene import build
from aerial_synth.scene.model import LABEL_IDS, Scene, SceneObject
from aerial_synth.scene.raycast import VEHICLES_ONLY, RayScene

from .worlds import make_placement, make_scene

CROWNS = [(8.5, -1.0), (0.5, 3.5), (-7.0, -2.5), (14.0, 6.0)]
SPECS = [
    (1, 0.0, 0.0, 0.0, 9.0, 2.5, 3.5),
    (2, 0.0, 2.9, 0.0, 4.5, 1.8, 1.4),
    (3, 8.0, -2.0, 0.4, 4.5, 1.8, 1.5),
    (4, -7.5, -1.5, 2.0, 4.2, 1.8, 1.45),
    (5, 14.5, 5.0, 1.2, 4.5, 1.8, 1.5),
    (6, 22.0, 8.0, 0.0, 4.5, 1.8, 1.5),
]


def _scene() -> Scene:
    """make_scene's ground, road, marking and house, with four crowns (and trunks) over
    or beside vehicles."""
    objs = list(make_scene(building=True).objects)
    for k, (x, y) in enumerate(CROWNS):
        v, f = build.ellipsoid((x, y, 6.0), (3.0, 3.0, 2.0), 2)
        objs.append(SceneObject(f"crown{k}", "tree", v, f))
        v, f = build.cylinder((x, y), 0.25, 0.0, 4.5)
        objs.append(SceneObject(f"trunk{k}", "trunk", v, f))
    return Scene("occl", objs)


def _world() -> tuple[RayScene, object]:
    from aerial_synth.render.world import add_placement

    rs = RayScene(_scene())
    pl = make_placement(SPECS)
    add_placement(rs, pl, simple_boxes=True)
    return rs, pl


def _rays(rng: np.random.Generator) -> np.ndarray:
    """(n, 6) float32: random rays in the scene's box, rays aimed at points on and near the
    crowns' and vehicles' surfaces (grazing ones included), and sun-ward shadow rays from
    the ground and the roofs."""
    out = []
    n = 3000
    o = rng.uniform([-15, -8, 0.05], [25, 12, 12], (n, 3))
    d = rng.normal(size=(n, 3))
    out.append(np.hstack([o, d]))
    targets = np.array([(x, y, 6.0) for x, y in CROWNS] + [(s[1], s[2], 0.8) for s in SPECS])
    radii = np.array([(3.0, 3.0, 2.0)] * len(CROWNS) + [(s[4] / 2, s[4] / 2, 0.8) for s in SPECS])
    k = rng.integers(0, len(targets), 6000)
    u = rng.normal(size=(6000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    p = targets[k] + u * radii[k] * rng.uniform(0.9, 1.1, (6000, 1))  # near the surface
    d = rng.normal(size=(6000, 3))
    out.append(np.hstack([p - d * rng.uniform(3, 20, (6000, 1)), d]))
    sun = np.array([0.5, 0.3, 0.8])
    o = rng.uniform([-15, -8, 0.0], [25, 12, 0.0], (3000, 3))
    o[:, 2] = np.where(rng.random(3000) < 0.3, 1.5, 0.01)
    d = sun + rng.normal(scale=0.1, size=(3000, 3))
    out.append(np.hstack([o, d]))
    return np.ascontiguousarray(np.concatenate(out), dtype=np.float32)


LIMITS = [(0.0, np.inf), (0.05, np.inf), (0.05, 6.0), (2.0, 9.0)]


@pytest.mark.parametrize("ignore", [{"tree"}, {"tree", "trunk"}, {"building", "tree"}, set()])
def test_union_equals_a_dedicated_build(ignore):
    ign = frozenset(ignore)
    rs, _ = _world()
    rays = _rays(np.random.default_rng(len(ignore)))
    union = [rs.test_occlusions(rays, ignore=ign, tnear=a, tfar=b) for a, b in LIMITS]
    assert ign not in rs._built  # answered without a build of every vehicle
    assert VEHICLES_ONLY in rs._built
    # both halves of the union matter on these rays
    static = rs._static_only(ign)
    vehicles = rs._get_built(VEHICLES_ONLY)
    s_hit = RayScene._occluded(static, rays, 0.0, np.inf)
    v_hit = RayScene._occluded(vehicles, rays, 0.0, np.inf)
    assert (s_hit & ~v_hit).sum() > 1000 and (v_hit & ~s_hit).sum() > 200
    assert (s_hit & v_hit).sum() > 100
    rs._get_built(ign)  # the old way: one scene of the static faces kept and all vehicles
    assert ign in rs._built
    single = [rs.test_occlusions(rays, ignore=ign, tnear=a, tfar=b) for a, b in LIMITS]
    for (a, b), u, s in zip(LIMITS, union, single):
        assert u.dtype == bool and s.dtype == bool
        np.testing.assert_array_equal(u, s, err_msg=f"tnear={a} tfar={b}")
    # and the tree crowns matter: ignoring them lets rays through
    if "tree" in ign:
        assert (rs.test_occlusions(rays) & ~union[0]).sum() > 200


def test_static_builds_survive_vehicle_changes_and_keep_their_layout():
    rs = RayScene(_scene())
    tree = frozenset({"tree"})
    before = rs._get_built(tree)
    keep = np.flatnonzero(rs._static_face_label != LABEL_IDS["tree"])
    assert list(before.geom_face_base) == [0]
    np.testing.assert_array_equal(before.geom_face_base[0], keep)
    labels = rs.trace_labels(np.array([[8.5, -1.0], [0.0, 0.0]]))
    from aerial_synth.render.world import add_placement

    add_placement(rs, make_placement(SPECS), simple_boxes=True)
    # a trace that ignores the vehicles is the static scene; one that sees them is not
    assert rs._get_built(tree | {"vehicle"}) is not before  # its own key, as before
    assert rs._get_built(tree) is not before
    assert rs._static_only(tree) is before
    rays = _rays(np.random.default_rng(5))
    rs.test_occlusions(rays, ignore=("tree",))
    assert rs._static_only(tree) is before
    rs.remove_vehicle(1)
    rs.clear_vehicles()
    assert rs._get_built(tree) is before  # no vehicles: the same scene as before them
    np.testing.assert_array_equal(rs.trace_labels(np.array([[8.5, -1.0], [0.0, 0.0]])), labels)


def test_union_vehicle_half_is_the_amodal_scene():
    rs, _ = _world()
    rs.test_occlusions(_rays(np.random.default_rng(1)), ignore=("tree",))
    vo = rs._built[VEHICLES_ONLY]
    rs.cast_rays(np.array([[0, 0, 50, 0, 0, -1]], np.float32), ignore=VEHICLES_ONLY)
    assert rs._built[VEHICLES_ONLY] is vo


def _spy_builds(monkeypatch, delay_s: float = 0.0):
    """Replace open3d's RaycastingScene, as the RayScene sees it, by one that records the
    triangle count of every geometry added: returns the list of builds (lists of counts).
    ``delay_s``: each new scene first sleeps that long (widens the window of a race)."""
    import time

    real = rc._o3d()
    builds: list[list[int]] = []

    class Spy:
        def __init__(self, *a, **kw):
            time.sleep(delay_s)
            self._sc = real.t.geometry.RaycastingScene(*a, **kw)
            self.counts: list[int] = []
            builds.append(self.counts)

        def add_triangles(self, v, f):
            self.counts.append(int(f.shape[0]))
            return self._sc.add_triangles(v, f)

        def __getattr__(self, name):
            return getattr(self._sc, name)

    fake = SimpleNamespace(core=real.core,
                           t=SimpleNamespace(geometry=SimpleNamespace(RaycastingScene=Spy)))
    monkeypatch.setattr(rc, "_o3d", lambda: fake)
    return builds


@pytest.mark.parametrize("primary", ["raster", "embree"])
def test_rendering_builds_no_scene_with_vehicles_but_without_trees(monkeypatch, primary):
    from aerial_synth.render import buffers as render_raycast
    from aerial_synth.render.world import add_placement

    monkeypatch.setattr(render_raycast, "PRIMARY", primary)

    builds = _spy_builds(monkeypatch)
    rs = RayScene(_scene())
    rs.trace_labels(np.array([[0.0, 0.0], [8.5, -1.0]]))  # placement's probes (ignore trees)
    add_placement(rs, make_placement(SPECS), simple_boxes=True)
    rs.refresh()
    n_static = len(rs._static_faces)
    n_tree = int((rs._static_face_label == LABEL_IDS["tree"]).sum())
    n_veh = len(rs._veh_faces)
    assert len({n_static, n_static - n_tree, n_veh}) == 3  # the counts tell builds apart
    assert builds == [[n_static - n_tree]]
    del builds[:]
    tree_tests = []
    orig = rs.test_occlusions

    def spy(rays, ignore=(), **kw):
        if frozenset(ignore) == {"tree"}:
            tree_tests.append(len(rays))
        return orig(rays, ignore=ignore, **kw)

    rs.test_occlusions = spy
    cfg = CameraConfig(width_px=192, height_px=160, gsd_m=0.15)
    for k, pose in enumerate([dict(), dict(tilt_deg=20.0, tilt_axis_deg=60.0)]):
        cam = Camera.look_at_ground(cfg, (3.0, 1.0, 0.0), **pose)
        render_frame(rs, cam, make_placement(SPECS), np.random.default_rng(k),
                     config=RenderConfig(sun_elevation_deg=(40.0, 40.0)))
    assert sum(tree_tests) > 0  # the crown-gap test ran
    # the vehicles-only scene (amodal masks, the unions' vehicle half) once; the static
    # {"tree"} scene from placement is reused. The z-buffer primary (render/raster.py)
    # needs no Embree scene, so shadow rays are a union too: the static scene (kept across
    # vehicle changes) and the vehicles; an Embree primary builds the full scene once.
    if primary == "raster":
        assert sorted(builds) == sorted([[n_static], [n_veh]])
    else:
        assert sorted(builds) == sorted([[n_static, n_veh], [n_veh]])


def test_threads_never_build_the_same_scene_twice(monkeypatch):
    """The visibility thread and the shader may ask for the vehicles-only scene at once."""
    import threading

    rs, _ = _world()
    rs._static_only(frozenset({"tree"}))  # as placement left it: the union's static half
    builds = _spy_builds(monkeypatch, delay_s=0.05)
    rays = _rays(np.random.default_rng(2))[:500]
    barrier = threading.Barrier(4)
    errors = []

    def work(k):
        try:
            barrier.wait()
            if k % 2:
                rs.test_occlusions(rays, ignore=("tree",))
            else:
                rs.cast_rays(rays, ignore=VEHICLES_ONLY)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert builds == [[len(rs._veh_faces)]]  # the vehicles-only scene, once
    assert frozenset({"tree"}) not in rs._built
