"""open3d without its plotly viewer, for the processes aerial-synth owns.

``import open3d`` takes ~1.1-1.7 s, about half of it in
``open3d.visualization.draw_plotly``, which imports Dash and Plotly for a notebook viewer
aerial-synth never uses. The export pool's fork server (:mod:`.dataset.engines._server_open3d`) and
the ``aerial-synth`` command (:func:`aerial_synth.cli.console_main`) put a stub module in
its place before open3d is imported: ``scene``, ``place`` and ``export`` start ~0.4 s
sooner (open3d's import: 0.72 -> 0.32 s). A library user's process is left alone (``aerial_synth.cli.main`` called as a
function installs nothing). The stub is put in place only when the installed open3d's
``visualization/__init__.py`` (read from disk, not imported) takes nothing from the viewer
but the three names the stub has: an open3d that failed halfway through its import could
not be imported again in the same process (its compiled types are registered once).
"""

from __future__ import annotations

import re
import sys
import types

__all__ = ["VIEWER", "stub_fits", "stub_viewer"]

VIEWER = "open3d.visualization.draw_plotly"
_NAMES = ("get_plotly_fig", "draw_plotly", "draw_plotly_server")
_DOC = "stub: see aerial_synth._open3d"


def _absent(*args, **kwargs):
    raise RuntimeError("open3d's plotly viewer is not loaded in this aerial-synth process")


_FROM_VIEWER = re.compile(r"from[ \t]+\.draw_plotly[ \t]+import[ \t]+(\([^)]*\)|[^\n#;]*)")


def stub_fits(source: str) -> bool:
    """Whether an ``open3d/visualization/__init__.py`` with this ``source`` takes from the
    viewer nothing but the names the stub has (so open3d imports beside it)."""
    names = []
    for m in _FROM_VIEWER.finditer(source):
        names += [n.strip() for n in m.group(1).strip("()").split(",") if n.strip()]
    rest = _FROM_VIEWER.sub("", source)
    return bool(names) and set(names) <= set(_NAMES) and re.search(r"draw_plotly\b", rest) is None


def _installed_fits() -> bool:
    """:func:`stub_fits` for the installed open3d, read from disk (nothing imported)."""
    import importlib.util
    from pathlib import Path

    try:
        spec = importlib.util.find_spec("open3d")
    except (ImportError, ValueError):
        return False
    if spec is None or not spec.submodule_search_locations:
        return False
    init = Path(list(spec.submodule_search_locations)[0]) / "visualization" / "__init__.py"
    try:
        return stub_fits(init.read_text(encoding="utf-8"))  # guard: open3d's own __init__.py
    except OSError:
        return False


def stub_viewer() -> bool:
    """Put the stub in place of open3d's plotly viewer if open3d is not imported yet and
    the installed open3d takes only the stub's names from it; returns whether it did."""
    if "open3d" in sys.modules or VIEWER in sys.modules or not _installed_fits():
        return False
    stub = types.ModuleType(VIEWER, _DOC)
    for name in _NAMES:
        setattr(stub, name, _absent)
    sys.modules[VIEWER] = stub
    return True
