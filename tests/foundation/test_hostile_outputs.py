"""Every writing command, given an impossible output, prints one line, exits 2 and leaves the
file system as it was: an existing file where a folder is expected, a path below a file,
a device, and (as an unprivileged user) a read-only folder."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from aerial_synth.cli import main

# (argv before the output path, what kind of output: "file" or "dir")
WRITERS = [
    (["scene", "show", "city_park", "--out"], "file", "map.png"),
    (["scene", "export", "city_park", "--out"], "file", "scene.glb"),
    (["assets", "preview", "--out"], "file", "sheet.png"),
    (["place", "--scenario", "sparse", "--vehicles", "5", "--no-png", "--out"], "dir", "pl"),
    (["render", "--vehicles", "5", "--width", "64", "--height", "64", "--out"], "dir", "fr"),
    (["export", "--images", "1", "--size", "64", "--simple-vehicles", "--no-progress",
      "--out"], "dir", "ds"),
]


def _snapshot(folder: Path):
    out = []
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        data = p.read_bytes() if stat.S_ISREG(st.st_mode) else b""
        out.append((str(p.relative_to(folder)), st.st_mode, data))
    return out


def _run(capsys, argv):
    code = main(argv)
    return code, capsys.readouterr().err


def _device(path: Path) -> Path:
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except OSError:
        os.mkfifo(path)
    return path


@pytest.mark.parametrize("argv, kind, name", WRITERS, ids=[" ".join(w[0][:2]) for w in WRITERS])
def test_output_below_a_file(capsys, tmp_path, argv, kind, name):
    (tmp_path / "afile").write_text("keep")
    before = _snapshot(tmp_path)
    code, err = _run(capsys, argv + [str(tmp_path / "afile" / "sub" / name)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("argv, kind, name", WRITERS, ids=[" ".join(w[0][:2]) for w in WRITERS])
def test_output_is_a_device(capsys, tmp_path, argv, kind, name):
    dev = _device(tmp_path / name)
    before = _snapshot(tmp_path)
    code, err = _run(capsys, argv + [str(dev)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("argv, kind, name", [w for w in WRITERS if w[1] == "dir"],
                         ids=[" ".join(w[0][:1]) for w in WRITERS if w[1] == "dir"])
def test_folder_output_is_a_file(capsys, tmp_path, argv, kind, name):
    f = tmp_path / name
    f.write_text("keep")
    before = _snapshot(tmp_path)
    code, err = _run(capsys, argv + [str(f)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert _snapshot(tmp_path) == before


def _unprivileged():
    """argv prefix that runs a command as 'nobody' (root here), or None if impossible."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        return None
    return [setpriv, "--reuid=65534", "--regid=65534", "--clear-groups"]


@pytest.mark.parametrize("argv, kind, name", WRITERS, ids=[" ".join(w[0][:2]) for w in WRITERS])
def test_read_only_folder(tmp_path, argv, kind, name):
    prefix = _unprivileged()
    if prefix is None:
        pytest.skip("running as root without setpriv: read-only folders cannot be tested")
    base = tmp_path / "base"
    base.mkdir()
    ro = base / "ro"
    ro.mkdir()
    os.chmod(tmp_path, 0o755)
    os.chmod(base, 0o777)
    if prefix:
        os.chown(ro, 65534, 65534)
    os.chmod(ro, 0o555)
    before = _snapshot(base)
    env = dict(os.environ, HOME=str(base))
    res = subprocess.run(prefix + [sys.executable, "-m", "aerial_synth.cli"] + argv
                         + [str(ro / "sub" / name)], capture_output=True, text=True, env=env,
                         timeout=300, cwd=base)
    after = _snapshot(base)
    os.chmod(ro, 0o755)
    assert res.returncode == 2, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "Traceback" not in res.stderr
    assert after == before
