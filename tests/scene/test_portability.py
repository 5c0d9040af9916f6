"""One seed, one scene on every x86-64 machine (under the committed lock).

- The bundled scenes match their cross-machine fingerprint (counts, bounds to 1 mm, areas to
  1 cm², the label layout at 0.5 m): tests/scene/data/fingerprints/*.json, written by
  tools/pin_scene_fingerprints.py. The exact hashes are ``lock_exact`` (make test-exact).
- On this machine, the CPU-specific code paths of the libraries (OpenBLAS's kernel, glibc's
  FMA variants, numpy's SIMD dispatch, thread counts) do not change a bit of a scene: the
  residential_us difference of issue 36 came from OpenBLAS's AVX-512 ``ddot`` under
  ``np.linalg.norm`` of 2-vectors, and a flipped diagonal in a trampoline's ring.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from aerial_synth.scene import load_scene
from aerial_synth.scene.build import GRID_M, prism, snap_to_grid, triangulate_polygon
from aerial_synth.scene.fingerprint import compare_fingerprints, scene_fingerprint

REPO = Path(__file__).resolve().parents[2]
FP_DIR = Path(__file__).parent / "data" / "fingerprints"
BUNDLED = ("city_park", "suburb", "highway", "residential_us", "residential_eu", "rural")


@functools.lru_cache(maxsize=None)
def _scene(name):
    return load_scene(name)


@pytest.mark.lock_pinned  # the lock's versions (shapely 2.1 -> 2.2 moved every scene), any CPU
@pytest.mark.parametrize("name", BUNDLED)
def test_fingerprint_matches_pin(name):
    want = json.loads((FP_DIR / f"{name}.json").read_text())
    assert compare_fingerprints(scene_fingerprint(_scene(name)), want) == []


def _replace_object(scene, i, **kw):
    objs = list(scene.objects)
    objs[i] = dataclasses.replace(objs[i], **kw)
    return dataclasses.replace(scene, objects=objs)


def test_fingerprint_ignores_last_bits_and_flips_but_not_a_millimetre():
    sc = _scene("residential_us")
    base = scene_fingerprint(sc)
    i = next(k for k, o in enumerate(sc.objects) if o.name.startswith("house_building_paint"))
    o = sc.objects[i]
    # last bits: every coordinate one ulp up
    v = np.nextafter(o.vertices, np.inf)
    assert compare_fingerprints(scene_fingerprint(_replace_object(sc, i, vertices=v)), base) == []
    # a flipped diagonal: the ground's rectangle split along its other diagonal
    g = next(k for k, o in enumerate(sc.objects) if o.name == "ground")
    f = np.asarray(sc.objects[g].faces)
    assert f.shape == (2, 3)
    quad = _quad(f[0], f[1])
    flipped = np.array([quad[[0, 1, 2]], quad[[0, 2, 3]]])  # diagonal p-q, not s0-s1
    assert {frozenset(t) for t in flipped} != {frozenset(t) for t in f}
    assert compare_fingerprints(scene_fingerprint(_replace_object(sc, g, faces=flipped)), base) == []
    # one object moved by 2 mm east
    moved = np.asarray(o.vertices) + [0.002, 0.0, 0.0]
    diff = compare_fingerprints(scene_fingerprint(_replace_object(sc, i, vertices=moved)), base)
    assert any(o.name in d and "bounds" in d for d in diff), diff
    # one object relabelled: the layout and the label areas change
    road = next(k for k, o in enumerate(sc.objects) if o.label == "road")
    diff = compare_fingerprints(scene_fingerprint(_replace_object(sc, road, label="parking")), base)
    assert any("label layout" in d for d in diff) and any(d.startswith("label road") for d in diff)


def _quad(t1, t2):
    """The four corners (in order round the quad) of two triangles sharing an edge."""
    shared = [x for x in t1 if x in t2]
    p = next(x for x in t1 if x not in shared)
    q = next(x for x in t2 if x not in shared)
    # t1 = (p, s0, s1) in its winding; the quad is p, s0, q, s1
    k = list(t1).index(p)
    s0, s1 = t1[(k + 1) % 3], t1[(k + 2) % 3]
    return np.array([p, s0, q, s1])


def test_snap_is_exact_and_idempotent():
    x = np.array([0.1, -123.456789012345, 1e-9, 2.5 * GRID_M, -0.0])
    s = snap_to_grid(x)
    assert np.array_equal(snap_to_grid(s), s)
    assert np.all(np.abs(s - x) <= GRID_M / 2)
    assert np.array_equal(s / GRID_M, np.rint(s / GRID_M))  # on the grid, exactly
    assert not np.signbit(s[-1])


def test_ring_triangulation_does_not_flip_on_last_bits():
    """A disc's ring (cocircular corners): the triangulation of its points one ulp apart is
    the same, as it was not before the snap (a trampoline of residential_us, issue 36)."""
    disc = shapely.Point(143.9, 35.9).buffer(2.0, quad_segs=6)
    nudged = shapely.transform(disc, lambda c: np.nextafter(c, np.inf))
    (va, fa), (vb, fb) = triangulate_polygon(disc), triangulate_polygon(nudged)
    assert np.array_equal(va, vb) and np.array_equal(fa, fb)
    v, f = prism(disc, 0.84, 0.92)  # walls meet the top: their corners are the top's
    top = {tuple(p) for p in v[np.isclose(v[:, 2], 0.92)][:, :2]}
    assert top == {tuple(p) for p in va}


#: CPU-specific code paths a machine may take, switched here one at a time and all at once.
_DISPATCH = ("X86_V3", "X86_V4", "AVX512_ICL", "AVX512_SPR")
_VARIANTS = {
    "openblas_nehalem": {"OPENBLAS_CORETYPE": "Nehalem"},
    "glibc_no_fma_avx2_avx512": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-FMA,-AVX2,-AVX512F"},
    "numpy_baseline_only": {"NPY_DISABLE_CPU_FEATURES": " ".join(_DISPATCH)},
    "one_thread": {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"},
}
_VARIANTS["all"] = {k: v for d in _VARIANTS.values() for k, v in d.items()}


def _numpy_env(env):
    """NPY_DISABLE_CPU_FEATURES names only the dispatch targets this numpy has."""
    from numpy._core._multiarray_umath import __cpu_dispatch__

    if "NPY_DISABLE_CPU_FEATURES" in env:
        env["NPY_DISABLE_CPU_FEATURES"] = " ".join(t for t in _DISPATCH if t in __cpu_dispatch__)
    return env


@pytest.mark.parametrize("variant", [
    pytest.param(v, marks=() if v == "all" else pytest.mark.slow) for v in _VARIANTS])
def test_scene_bits_do_not_depend_on_cpu_code_paths(variant):
    code = ("import sys; from aerial_synth.scene import load_scene; "
            "print(*(load_scene(n).vertex_hash() for n in sys.argv[1:]))")
    names = ("residential_us", "city_park")
    env = _numpy_env(dict(os.environ, PYTHONPATH=str(REPO), **_VARIANTS[variant]))
    r = subprocess.run([sys.executable, "-c", code, *names], env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [_scene(n).vertex_hash() for n in names], variant
