"""The glibc allocator settings for rendering loops (aerial_synth.render.allocator):
large arrays a frame frees are reused by the next one instead of being mapped again."""

import os
import subprocess
import sys
import textwrap

import pytest

_PROBE = textwrap.dedent("""
    import ctypes, json, sys
    import numpy as np
    from aerial_synth.render.allocator import tune_allocator

    class MallInfo2(ctypes.Structure):
        _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks",
                    "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]

    libc = ctypes.CDLL(None)
    libc.mallinfo2.restype = MallInfo2
    tuned = tune_allocator() if sys.argv[1] == "tune" else None
    a = np.ones(24 << 20, np.uint8)  # the size of a 1024 px frame's pixel rays
    during = libc.mallinfo2()
    del a
    after = libc.mallinfo2()
    print(json.dumps({"tuned": tuned, "mapped": during.hblkhd, "heap_after": after.arena,
                      "free_after": after.fordblks}))
""")


def _probe(mode, **env):
    import json
    from pathlib import Path

    e = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    e["PYTHONPATH"] = str(Path(__file__).resolve().parents[2])
    e.update(env)
    r = subprocess.run([sys.executable, "-c", _PROBE, mode], capture_output=True, text=True, env=e,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def _glibc_with_mallinfo2() -> bool:
    import ctypes

    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # noqa: B018
        libc.mallinfo2  # noqa: B018 - glibc >= 2.33
    except (OSError, AttributeError):
        return False
    return sys.platform.startswith("linux")


pytestmark = pytest.mark.skipif(not _glibc_with_mallinfo2(), reason="glibc >= 2.33 only (mallinfo2)")


def test_tuned_process_keeps_a_frames_arrays_on_its_heap():
    plain = _probe("plain")
    tuned = _probe("tune")
    assert tuned["tuned"] is True
    # glibc's default: a fresh 24 MB block is its own mapping, returned when freed
    assert plain["mapped"] >= 24 << 20
    # tuned: it comes from the heap and stays there, free, for the next frame
    assert tuned["mapped"] < 24 << 20
    assert tuned["heap_after"] >= 24 << 20 and tuned["free_after"] >= 24 << 20


def test_user_malloc_settings_are_left_alone():
    got = _probe("tune", GLIBC_TUNABLES="glibc.malloc.trim_threshold=1000000")
    assert got["tuned"] is False
    assert got["mapped"] >= 24 << 20  # glibc's own threshold still maps the block
    assert _probe("tune", MALLOC_TRIM_THRESHOLD_="1000000")["tuned"] is False
