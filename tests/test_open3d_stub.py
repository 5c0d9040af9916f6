"""The ``aerial-synth`` command imports open3d without its plotly viewer; a library user's
process imports it as usual; an open3d that would take more from the viewer than the stub
has is imported in full (aerial_synth/_open3d.py). The processes are fresh interpreters."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

PROBE = """
import json, sys
from aerial_synth.scene.raycast import _o3d
o3d = _o3d()
import numpy as np
sc = o3d.t.geometry.RaycastingScene()
sc.add_triangles(o3d.core.Tensor(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)),
                 o3d.core.Tensor(np.array([[0, 1, 2]], np.uint32)))
t = sc.cast_rays(o3d.core.Tensor(np.array([[0.2, 0.2, 1, 0, 0, -1]], np.float32)))["t_hit"]
viewer = sys.modules.get("open3d.visualization.draw_plotly")
print(json.dumps({"rc": RC, "stub": "stub" in (getattr(viewer, "__doc__", "") or ""),
                  "dash": "dash" in sys.modules, "t": float(t.numpy()[0])}))
"""


def _run(prelude: str) -> dict:
    code = prelude + PROBE
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_command_stubs_the_viewer_and_ray_casting_works():
    r = _run("from aerial_synth.cli import console_main\nRC = console_main(['--version'])\n")
    assert r == {"rc": 0, "stub": True, "dash": False, "t": pytest.approx(1.0, abs=1e-6)}


def test_main_called_as_a_library_function_leaves_open3d_alone():
    r = _run("from aerial_synth.cli import main\nRC = main(['--version'])\n")
    assert r["rc"] == 0 and r["stub"] is False and r["t"] == pytest.approx(1.0, abs=1e-6)


def test_the_stub_goes_in_only_where_open3d_takes_just_its_names():
    from aerial_synth._open3d import _installed_fits, stub_fits

    assert _installed_fits()  # the pinned open3d: its visualization takes the three names
    ok = ("from .draw_plotly import get_plotly_fig\nfrom .draw_plotly import draw_plotly\n"
          "from .draw_plotly import draw_plotly_server\n")
    assert stub_fits(ok)
    assert stub_fits("from .draw_plotly import (draw_plotly,\n    get_plotly_fig)\n")
    assert not stub_fits(ok + "from .draw_plotly import PlotlyApp\n")  # a name it lacks
    assert not stub_fits(ok + "from . import draw_plotly\nx = draw_plotly.THEME\n")
    assert not stub_fits("from .other import thing\n")  # nothing recognisable: no stub
