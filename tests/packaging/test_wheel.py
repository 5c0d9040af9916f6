"""The wheel works without the checkout.

``python -m build`` makes an sdist and, from that sdist, a wheel (so both are checked). The
wheel goes into a new virtual environment outside the repository, with the locked
dependencies from uv's cache (``--offline``: nothing is downloaded; ``make test`` filled the
cache), and the installed ``aerial-synth`` runs ``place --scenario jam`` and a 2-image export
from a folder outside the repository. Bundled scenes, scenarios and vehicle assets can then
only come from the wheel's package data.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from aerial_synth import __version__

REPO = Path(__file__).resolve().parents[2]
UV = Path(sys.prefix) / "bin" / "uv"
_SKIP_COPY = shutil.ignore_patterns(".venv*", ".git", "out", "build", "dist", "*.egg-info",
                                    "__pycache__", ".pytest_cache", ".ruff_cache", ".hypothesis")


def _run(cmd, cwd, env=None, timeout=600):
    r = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, f"{cmd[:3]} exited {r.returncode}:\n{r.stdout[-2000:]}\n{r.stderr[-4000:]}"
    return r


@pytest.fixture(scope="module")
def dist(tmp_path_factory):
    """sdist and wheel built from a copy of the source tree (the build writes build/ and
    *.egg-info beside the sources; the checkout stays untouched)."""
    root = tmp_path_factory.mktemp("wheel")
    src = root / "src"
    shutil.copytree(REPO, src, ignore=_SKIP_COPY, symlinks=True)
    _run([sys.executable, "-m", "build", "--no-isolation", "--outdir", root / "dist", src], root)
    wheels = list((root / "dist").glob("aerial_synth-*.whl"))
    sdists = list((root / "dist").glob("aerial_synth-*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, list((root / "dist").iterdir())
    return root, wheels[0], sdists[0]


@pytest.mark.slow
def test_wheel_holds_the_package_data(dist):
    _, wheel, _ = dist
    assert wheel.name == f"aerial_synth-{__version__}-py3-none-any.whl"
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
    for scene in (REPO / "scenes").glob("*.yaml"):
        assert f"aerial_synth/data/scenes/{scene.name}" in names
    for scenario in (REPO / "scenes" / "scenarios").glob("*.yaml"):
        assert f"aerial_synth/data/scenes/scenarios/{scenario.name}" in names
    assert "aerial_synth/data/vehicle_assets/catalog.yaml" in names
    assert not [n for n in names if n.startswith(("tests/", "tools/"))]


@pytest.mark.slow
def test_installed_wheel_places_and_exports_outside_the_checkout(dist):
    if not UV.exists():
        pytest.fail(f"{UV} is missing: the test venv is made by `make test`, which installs uv")
    root, wheel, _ = dist
    venv = root / "venv"
    _run([sys.executable, "-m", "venv", venv], root)
    py = venv / "bin" / "python"
    # the locked runtime dependencies, from uv's cache only; then the wheel alone
    _run([UV, "pip", "install", "-q", "--offline", "--python", py, "-r", REPO / "pylock.toml"], root)
    _run([UV, "pip", "install", "-q", "--offline", "--no-deps", "--python", py, wheel], root)
    work = root / "work"  # outside the repository: nothing there to find scenes in
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    exe = venv / "bin" / "aerial-synth"
    where = _run([py, "-c", "import aerial_synth; print(aerial_synth.__file__)"], work, env).stdout
    assert Path(where.strip()).is_relative_to(venv), where
    assert _run([exe, "--version"], work, env).stdout.strip() == f"aerial-synth {__version__}"

    _run([exe, "place", "--scenario", "jam", "--out", work / "place", "--no-png"], work, env)
    placement = json.loads((work / "place" / "placement.json").read_text())
    assert placement["scene"] == "city_park" and len(placement["vehicles"]) > 50
    assert placement["versions"]["aerial-synth"] == __version__

    _run([exe, "export", "--scene", "suburb", "--scenario", "parking", "--images", "2", "--size", "256",
          "--format", "dota,yolo-obb", "--seed", "1", "--no-progress", "--out", work / "ds"],
         work, env)
    manifest = json.loads((work / "ds" / "manifest.json").read_text())
    assert manifest["status"] == "complete" and manifest["versions"]["aerial-synth"] == __version__
    labels = sorted((work / "ds" / "dota").rglob("labelTxt/*.txt"))
    assert len(labels) == 2
    assert sum(len(p.read_text().splitlines()) for p in labels) > 2  # gsd header + boxes
