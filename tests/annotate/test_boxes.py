import math

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiPoint

from aerial_synth.annotate import (
    BoxConfig,
    OrientedBox,
    VehicleAnnotation,
    annotate_instances,
    heading_deg_from_vector,
    mask_to_rect_corners,
    order_corners,
    shoelace_area,
)
from aerial_synth.errors import ConfigError

from .synthetic import NadirCamera, render_instance, silhouette, vehicle


def _angle_diff(a, b):
    return abs((a - b + 180.0) % 360.0 - 180.0)


def _by_id(anns):
    return {a.vehicle_id: a for a in anns}


def test_heading_convention():
    assert heading_deg_from_vector([1, 0]) == 0.0
    assert heading_deg_from_vector([0, -1]) == pytest.approx(90.0)
    assert heading_deg_from_vector([-1, 0]) == pytest.approx(180.0)
    assert heading_deg_from_vector([0, 1]) == pytest.approx(270.0)


@pytest.mark.parametrize("fwd", [(0, -1), (1, 0), (0, 1), (-1, 0), (1, -1), (-3, 2)])
def test_order_corners_clockwise_from_front_left(fwd):
    f = np.array(fwd, float) / np.linalg.norm(fwd)
    left = np.array([f[1], -f[0]])
    c = np.array([50.0, 60.0])
    # rectangle 40 long x 16 wide, corners shuffled
    pts = [c + s * 20 * f + t * 8 * left for s, t in ((1, 1), (-1, 1), (1, -1), (-1, -1))]
    ring = np.array(pts)[[1, 0, 2, 3]]  # RL, FL, FR, RR: around the rectangle, rotated
    out = order_corners(ring[::-1], f)  # and counter-clockwise
    assert shoelace_area(out) > 0
    np.testing.assert_allclose(out[0], c + 20 * f + 8 * left, atol=1e-9)  # front-left
    np.testing.assert_allclose(out[1], c + 20 * f - 8 * left, atol=1e-9)  # front-right
    box = OrientedBox.from_corners(out)
    assert box.w_px == pytest.approx(16) and box.h_px == pytest.approx(40)
    assert _angle_diff(box.angle_deg, heading_deg_from_vector(f)) < 1e-6


def test_order_corners_nadir_up_is_top_left():
    # vehicle driving up the screen: front-left corner is the top-left one
    rect = np.array([[10, 10], [20, 10], [20, 40], [10, 40]], float)
    out = order_corners(rect, [0, -1])
    np.testing.assert_allclose(out, [[10, 10], [20, 10], [20, 40], [10, 40]])


def test_mask_to_rect_axis_aligned_exact():
    m = np.zeros((20, 40), bool)
    m[5:15, 3:33] = True  # 30 x 10 px block at x 3..33, y 5..15
    c = mask_to_rect_corners(m, (100, 200))
    lo, hi = c.min(0), c.max(0)
    np.testing.assert_allclose(lo, [103.25, 205.25], atol=1e-6)  # pixel centres + 0.25 px
    np.testing.assert_allclose(hi, [132.75, 214.75], atol=1e-6)
    lit = mask_to_rect_corners(m, (100, 200), fit="dilated")  # thesis: dilated contour
    np.testing.assert_allclose(lit.min(0), [102.5, 204.5], atol=1e-6)


def test_mask_largest_region_kept():
    m = np.zeros((30, 60), bool)
    m[2:8, 2:10] = True  # small
    m[12:28, 20:58] = True  # large
    c = mask_to_rect_corners(m)
    assert c.min(0)[0] > 15


def test_empty_mask():
    assert mask_to_rect_corners(np.zeros((4, 4), bool)) is None


@pytest.mark.parametrize("heading", [0, 17, 45, 90, 123, 180, 211, 270, 333])
@pytest.mark.parametrize("where", [(0.0, 0.0), (20.0, -14.0), (-35.0, 30.0)])
def test_mask_box_matches_projected_footprint_at_nadir(heading, where):
    cam = NadirCamera()  # 12 cm GSD, nadir
    assert cam.gsd_m == pytest.approx(0.12)
    vehs = [vehicle(1, *where, heading_deg=heading), vehicle(2, where[0] + 8, where[1] + 8,
            heading_deg=heading + 90, length=9.0, width=2.5, height=3.2, cls="large-vehicle")]
    inst = render_instance(cam, vehs)
    anns = _by_id(annotate_instances(inst, {v.id: v for v in vehs}, cam.project))
    for v in vehs:
        a = anns[v.id]
        assert a.status == "kept"
        box = shapely.Polygon(a.box.corners)
        ref = MultiPoint(cam.project(np.r_[np.c_[v.corners_xy(), np.zeros(4)],
                                          np.c_[v.corners_xy(), np.full(4, v.height_m)]])).minimum_rotated_rectangle
        iou = box.intersection(ref).area / box.union(ref).area
        assert iou >= 0.85, (v.id, iou)
        true_heading = heading_deg_from_vector(cam.project([[v.x_m + math.cos(v.heading_rad), v.y_m + math.sin(v.heading_rad), 0]])[0] - cam.project([[v.x_m, v.y_m, 0]])[0])
        assert _angle_diff(a.heading_img_deg, true_heading) < 1e-6
        assert _angle_diff(a.box.angle_deg, true_heading) <= 5.0
        assert shoelace_area(a.box.corners) > 0
        # first corner is the front-left one of the projected cuboid
        fl_world = v.corners_xy()[0]
        fl = cam.project([[*fl_world, v.height_m / 2]])[0]
        d = np.linalg.norm(a.box.corners - fl, axis=1)
        assert np.argmin(d) == 0


def test_heading_with_camera_twist():
    cam = NadirCamera(yaw_rad=math.radians(30))
    v = vehicle(1, heading_deg=0)
    a = annotate_instances(render_instance(cam, [v]), {1: v}, cam.project)[0]
    # camera twisted +30 deg: an eastbound vehicle appears rotated by -30 deg on screen
    assert _angle_diff(a.heading_img_deg, 330.0) < 1e-6
    assert _angle_diff(a.box.angle_deg, 330.0) < 5


class _Vis:
    def __init__(self, visible_px, amodal_px, truncated=False):
        self.visible_px, self.amodal_px = visible_px, amodal_px
        self.visible_fraction = visible_px / amodal_px if amodal_px else 0.0
        self.truncated = truncated


def test_flags_difficult_dropped_and_reasons():
    cam = NadirCamera(width_px=256, height_px=256)
    vs = {i: vehicle(i, x=-8 + 6 * (i - 1), heading_deg=90) for i in (1, 2, 3, 4)}
    vs[5] = vehicle(5, x=15.0, y=0.0, heading_deg=0)  # cut by the right border (256 px ~ 15 m)
    inst = render_instance(cam, [v for i, v in vs.items() if i != 4])  # 4 is hidden
    counts = {i: int((inst == i).sum()) for i in vs}
    vis = {
        1: _Vis(counts[1], counts[1]),  # fully visible
        2: _Vis(counts[2], int(counts[2] / 0.3)),  # 30 % visible -> difficult
        3: _Vis(counts[3], int(counts[3] / 0.05)),  # 5 % visible -> dropped
        4: _Vis(0, 500),  # hidden -> dropped, not visible
        5: _Vis(counts[5], counts[5] * 2, truncated=True),
    }
    anns = _by_id(annotate_instances(inst, vs, cam.project, visibility=vis))
    assert anns[1].status == "kept" and anns[1].reasons == ()
    assert anns[2].status == "difficult" and anns[2].reasons == ("low_visible_fraction",)
    assert anns[3].status == "dropped" and "low_visible_fraction" in anns[3].reasons
    assert anns[4].status == "dropped" and anns[4].reasons == ("not_visible",)
    assert anns[5].status == "difficult" and "truncated" in anns[5].reasons


def test_too_few_pixels_dropped_and_configurable():
    cam = NadirCamera(width_px=128, height_px=128, focal_px=50)  # 1.2 m GSD: a car is ~15 px
    v = vehicle(1)
    inst = render_instance(cam, [v])
    n = int((inst == 1).sum())
    assert 0 < n < 20
    assert annotate_instances(inst, {1: v}, cam.project)[0].reasons == ("too_few_pixels",)
    kept = annotate_instances(inst, {1: v}, cam.project, BoxConfig(min_visible_px=1))[0]
    assert kept.kept


def test_occlusion_keeps_largest_region():
    cam = NadirCamera(width_px=256, height_px=256)
    long_truck = vehicle(1, heading_deg=0, length=12.0, width=2.5, height=1.0, cls="large-vehicle")
    bar = vehicle(2, x=-2.0, heading_deg=90, length=6.0, width=1.0, height=3.0)  # splits it
    inst = render_instance(cam, [long_truck, bar])
    a = _by_id(annotate_instances(inst, {1: long_truck, 2: bar}, cam.project))[1]
    # the larger (front) part is kept: its box lies right of the bar
    assert a.box.cx_px > cam.project([[-2.0, 0, 0]])[0][0]


def test_amodal_box_covers_hidden_part():
    cam = NadirCamera(width_px=256, height_px=256)
    car = vehicle(1, heading_deg=30)
    roof = vehicle(2, x=1.5, y=1.0, heading_deg=30, length=3.0, width=3.0, height=4.0)
    inst = render_instance(cam, [car, roof])
    vs = {1: car, 2: roof}
    vis_box = _by_id(annotate_instances(inst, vs, cam.project))[1].box
    am = _by_id(annotate_instances(inst, vs, cam.project, BoxConfig(box="amodal")))[1].box
    ref = silhouette(cam, car).minimum_rotated_rectangle
    p = shapely.Polygon(am.corners)
    assert p.intersection(ref).area / p.union(ref).area > 0.95
    assert shapely.Polygon(vis_box.corners).area < 0.9 * p.area


def test_annotation_dict_round_trip():
    cam = NadirCamera(width_px=256, height_px=256)
    v = vehicle(1, heading_deg=77)
    a = annotate_instances(render_instance(cam, [v]), {1: v}, cam.project)[0]
    b = VehicleAnnotation.from_dict(a.to_dict())
    assert b.status == a.status and b.cls == a.cls
    np.testing.assert_allclose(b.box.corners, a.box.corners, atol=1e-3)


@pytest.mark.parametrize(
    "kw",
    [dict(box="both"), dict(kernel_px=0), dict(min_visible_fraction=1.5),
     dict(min_visible_px=-1), dict(orientation_min_aspect=0.5)],
)
def test_config_rejects_bad_values(kw):
    with pytest.raises(ConfigError):
        BoxConfig(**kw)


def test_sparse_huge_ids_annotate_as_small_ones():
    """A tiled world's instance ids reach billions: annotations are those of the same
    vehicles numbered 1..k, without an array as long as the largest id."""
    import dataclasses
    import resource

    from aerial_synth.annotate.boxes import instance_slices

    cam = NadirCamera()
    small = [vehicle(1, -6.0, 0.0), vehicle(2, 4.0, 3.0, heading_deg=70.0),
             vehicle(3, 0.0, -7.0, heading_deg=200.0, length=9.0, width=2.5, height=3.2,
                     cls="large-vehicle")]
    big_ids = {1: 2_000_000_017, 2: 1_999_999_001, 3: 2_100_000_000}
    big = [dataclasses.replace(v, id=big_ids[v.id]) for v in small]
    inst_small = render_instance(cam, small)
    inst_big = render_instance(cam, big)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    slices = instance_slices(inst_big)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0 < 200_000  # KiB
    assert slices == {big_ids[k]: s for k, s in instance_slices(inst_small).items()}
    a = annotate_instances(inst_small, {v.id: v for v in small}, cam.project)
    b = annotate_instances(inst_big, {v.id: v for v in big}, cam.project)
    assert [x.vehicle_id for x in b] == sorted(big_ids.values())
    by_small = {x.vehicle_id: x for x in a}
    for x in b:
        old = [k for k, v in big_ids.items() if v == x.vehicle_id][0]
        y = by_small[old]
        assert (x.status, x.visible_px, x.heading_img_deg) == (y.status, y.visible_px, y.heading_img_deg)
        assert np.array_equal(x.box.corners, y.box.corners)
