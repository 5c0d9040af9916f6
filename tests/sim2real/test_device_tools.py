"""tools/device_wheels.py: a wheel slimmed (parts left out, LZMA) still installs with pip and
imports; tools/plans: the committed plans are valid (torch-free, nothing downloaded)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import zipfile

import pytest

from ..helpers import REPO


def _tool():
    spec = importlib.util.spec_from_file_location("device_wheels", REPO / "tools" / "device_wheels.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_slim_wheel_installs_without_the_dropped_parts(tmp_path):
    w = tmp_path / "toy-1.0-py3-none-any.whl"
    files = {"toy/__init__.py": "VALUE = 42\n", "toy/big/data.bin": "x" * 100000,
             "toy/ops.so": "not a library", "toy-1.0.dist-info/METADATA": "Metadata-Version: 2.1\nName: toy\nVersion: 1.0\n",
             "toy-1.0.dist-info/WHEEL": "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n"}
    with zipfile.ZipFile(w, "w") as z:
        for n, t in files.items():
            z.writestr(n, t)
        z.writestr("toy-1.0.dist-info/RECORD", "".join(f"{n},,\n" for n in files) + "toy-1.0.dist-info/RECORD,,\n")
    _tool().slim(w, drop=("toy/big/", "toy/ops.so"))
    with zipfile.ZipFile(w) as z:
        names = z.namelist()
        assert all(i.compress_type == zipfile.ZIP_LZMA for i in z.infolist())
        record = z.read("toy-1.0.dist-info/RECORD").decode()
    assert "toy/big/data.bin" not in names and "toy/ops.so" not in names and "toy/__init__.py" in names
    assert "toy/__init__.py,sha256=" in record and "toy/big" not in record
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-index", "--no-deps", "--no-compile",
                        "--disable-pip-version-check", "--target", str(tmp_path / "site"), str(w)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-c", "import toy; print(toy.VALUE)"], capture_output=True, text=True,
                       env={"PYTHONPATH": str(tmp_path / "site")}, timeout=60)
    assert r.stdout.strip() == "42" and not (tmp_path / "site" / "toy" / "big").exists()


@pytest.mark.parametrize("name", ["why_mix_lost.yaml", "tiny_cpu.yaml"])
def test_committed_plans_parse(name, tmp_path):
    """Every key of the committed plans is known and their export options are the export's;
    the real set (.s2r/real, made by tools/make_dev_set.py) is replaced by a stand-in."""
    from aerial_synth.sim2real.cli import export_config
    from aerial_synth.sim2real.plan import load_plan

    from .conftest import box, write_real

    text = (REPO / "tools" / "plans" / name).read_text()
    write_real(tmp_path / "real" / "minsk_uav", "a", [box(10, 10, 30, 20)])
    plan = tmp_path / name
    plan.write_text(text.replace("real: ../../.s2r/real", f"real: {tmp_path / 'real'}"))
    p = load_plan(plan, export_config=export_config)
    assert p.baseline == "A" and len(p.seeds) >= 2 and all(a.kind == "export" for a in p.arms)
    if name == "why_mix_lost.yaml":
        assert [a.name for a in p.arms] == list("ABCDEF") and len(p.seeds) >= 3
        assert len({a.train for a in p.arms}) == 1 and p.arms[0].train.minutes == 3  # the same time each
        assert p.arm("F").spec.images == 4 * p.arm("A").spec.images
        assert p.arm("B").spec.gsd_range == p.arm("D").spec.gsd_range == (0.05, 0.3)
        assert p.arm("C").spec.gsd_range is None and p.arm("C").spec.scene_mix == p.arm("B").spec.scene_mix
        assert p.ignore_classes == {"ucas_aod": ("large-vehicle",)}
