"""Imports open3d in the export pool's fork server without its plotly viewer (imported by
that server only, before anything else imports open3d).

``import open3d`` takes ~1.1 s, half of it in ``open3d.visualization.draw_plotly``, which
imports Dash and Plotly for a notebook viewer no worker uses. The fork server's imports are
what every export with workers waits for before its first image (the scene loads in ~1.5 s
meanwhile), so that half is left out here: the submodule is a stub whose three functions
say they are not loaded. Workers are forks of the server and inherit the stubbed open3d;
the exporter itself and every other process import open3d as usual. Should a future open3d
import more from that submodule, the stub is dropped and open3d imported in full.
"""

from __future__ import annotations

import sys
import types

from ._server_guard import _in_fork_server

_VIEWER = "open3d.visualization.draw_plotly"
_NAMES = ("get_plotly_fig", "draw_plotly", "draw_plotly_server")


def _absent(*args, **kwargs):
    raise RuntimeError("open3d's plotly viewer is not loaded in aerial-synth's export workers")


def _import() -> bool:
    if not _in_fork_server() or "open3d" in sys.modules:
        return False
    stub = types.ModuleType(_VIEWER, "stub: see aerial_synth.dataset._server_open3d")
    for name in _NAMES:
        setattr(stub, name, _absent)
    sys.modules[_VIEWER] = stub
    try:
        import open3d  # noqa: F401
    except ImportError:  # another open3d: start again without the stub
        for name in [m for m in sys.modules if m == "open3d" or m.startswith("open3d.")]:
            del sys.modules[name]
        import open3d  # noqa: F401

        return False
    return True


STUBBED = _import()
