"""Imports open3d in the export pool's fork server without its plotly viewer (imported by
that server only, before anything else imports open3d).

``import open3d`` takes ~1.1 s, half of it in ``open3d.visualization.draw_plotly``, which
imports Dash and Plotly for a notebook viewer no worker uses. The fork server's imports are
what every export with workers waits for before its first image (the scene loads in ~1.5 s
meanwhile), so that half is left out here (:mod:`aerial_synth._open3d`): the submodule is a
stub whose three functions say they are not loaded. Workers are forks of the server and
inherit the stubbed open3d. The ``aerial-synth`` command stubs it in its own process too
(:func:`aerial_synth.cli.console_main`); a library user's process imports open3d as usual.
An open3d whose viewer module offers more than the stub has is imported in full.
"""

from __future__ import annotations

import sys

from ..._open3d import stub_viewer
from ._server_guard import in_fork_server


def _import() -> bool:
    """In the fork server: import open3d, without its viewer where the stub fits; returns
    whether the stub is in place."""
    if not in_fork_server() or "open3d" in sys.modules:
        return False
    stubbed = stub_viewer()
    import open3d  # noqa: F401

    return stubbed


STUBBED = _import()
