"""The closed convex solids of the procedural vehicle parts (vehicles/_hull.py)."""

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from aerial_synth.vehicles._hull import box, convex_hull


@pytest.mark.parametrize("seed", range(6))
def test_convex_hull_is_closed_outward_and_exact(seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(int(rng.integers(8, 60)), 3)) * rng.uniform(0.1, 3.0, 3)
    if seed % 2:  # coplanar facets (a cylinder), as the wheels have
        a = np.linspace(0, 2 * np.pi, 14, endpoint=False)
        pts = np.array([(np.cos(t), s, np.sin(t)) for t in a for s in (-0.1, 0.1)])
    v, f = convex_hull(pts)
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.is_winding_consistent
    assert m.volume == pytest.approx(ConvexHull(pts).volume, rel=1e-9)  # > 0: outward
    assert len(v) == len(ConvexHull(pts).vertices)  # only hull vertices kept


def test_box_is_the_axis_aligned_box_in_either_bound_order():
    v, f = box(2.0, -1.0, 0.5, 0.0, 1.0, 3.0)
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.is_winding_consistent
    assert m.volume == pytest.approx(3.0 * 0.5 * 2.0)
    np.testing.assert_allclose(m.bounds, [[-1.0, 0.0, 1.0], [2.0, 0.5, 3.0]])
