"""The render kernels compile once per machine, with one line said, and once for processes
that start together (aerial_synth.render.warm)."""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from aerial_synth.render import warm
from aerial_synth.render.frame import render_frame

REPO = Path(__file__).resolve().parents[2]


def test_every_render_kernel_is_checked():
    names = {d.py_func.__qualname__ for d in warm.kernels()}
    assert {"compose", "surface", "tone", "_raster", "box_union_pixels", "grid_rays"} <= names
    assert warm.missing_kernels() == []  # this checkout's cache is warm (the suite rendered)


@pytest.fixture
def cold(monkeypatch, tmp_path):
    """ensure_compiled on a pretend-empty cache whose lock file is in tmp_path; the tiny
    frames are recorded, not rendered."""
    frames = []
    monkeypatch.setattr(warm, "_done", False)
    monkeypatch.setattr(warm, "_cached_here", lambda d: False)
    monkeypatch.setattr(warm, "_lock_path", lambda ks: str(tmp_path / "lock"))
    monkeypatch.setattr(warm, "_tiny_frame", lambda render, preset: frames.append(preset))
    return frames, tmp_path / "lock"


def test_cold_cache_says_one_line_and_compiles_once(cold, capsys, monkeypatch):
    frames, _ = cold
    assert warm.ensure_compiled(render_frame) is True
    assert frames == ["full", "fast"]
    assert capsys.readouterr().err == "aerial-synth: compiling render kernels, once per machine...\n"
    assert warm.ensure_compiled(render_frame) is False and frames == ["full", "fast"]  # once per process


def test_warm_cache_is_silent_and_renders_nothing(cold, capsys, monkeypatch):
    frames, _ = cold
    monkeypatch.setattr(warm, "_cached_here", lambda d: True)
    assert warm.ensure_compiled(render_frame) is False
    assert frames == [] and capsys.readouterr().err == ""


def test_a_second_process_waits_for_the_first_and_says_nothing(cold, capsys):
    """Another process holds the compile lock: this one waits (silently) until it is
    released, then runs its tiny frames, which load what the other one cached."""
    frames, lock = cold
    fd = os.open(lock, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    done = threading.Event()
    t = threading.Thread(target=lambda: (warm.ensure_compiled(render_frame), done.set()))
    # flock locks belong to the open file description: a thread with its own open() of the
    # file contends like another process would
    t.start()
    time.sleep(0.5)
    assert not done.is_set() and frames == []  # waiting on the lock
    os.close(fd)
    t.join(30)
    assert done.is_set() and frames == ["full", "fast"]
    assert capsys.readouterr().err == ""  # the process that compiled said it, not this one


_PROBE = """
import sys
from aerial_synth.render import frame, warm
compiled = warm.ensure_compiled(frame.render_frame)
misses = sum(sum(d._cache_misses.values()) for d in warm.kernels())
print(int(compiled), misses, len(warm.missing_kernels()))
"""


@pytest.mark.slow  # compiles every render kernel on an empty cache: minutes on 2 busy cores
def test_two_processes_on_an_empty_cache_compile_once(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), PYTHONPATH=str(REPO))
    procs = [subprocess.Popen([sys.executable, "-c", _PROBE], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=1200) for p in procs]
    assert all(p.returncode == 0 for p in procs), [e for _, e in outs]
    said = [e.count("compiling render kernels, once per machine...") for _, e in outs]
    assert sorted(said) == [0, 1]
    rows = [tuple(int(x) for x in o.split()) for o, _ in outs]
    assert all(r[0] == 1 and r[2] == 0 for r in rows)  # both waited or compiled; all cached
    assert sorted(r[1] for r in rows)[0] == 0  # one of them compiled nothing: it loaded
    # a third process finds everything cached: silent, nothing compiled
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.stdout.split() == ["0", "0", "0"] and "compiling" not in out.stderr
