"""The wheels ``tools/sim2real_device.sh`` carries to a GPU machine, into ``.whl/`` (git-ignored
through .git/info/exclude): what aerial-synth's exports and sim2real need there besides the
machine's own Python (3.12 with torch, torchvision, numpy, scipy, numba, opencv-python-headless,
pyyaml, matplotlib, tqdm, pillow; see the device notes).

open3d is the large one (a 105 MB wheel, 228 MB of library): the CPU build ``open3d-cpu`` is
taken, the parts aerial-synth never loads are left out (GUI resources, the TensorFlow and torch
ops, open3d.ml, examples; an export was checked to run without them) and the rest is stored
with LZMA, so it fits the 64 MiB a call may carry together with the repository and the
development set. pip installs such a wheel as any other (zipfile reads LZMA members).

    python tools/device_wheels.py [--out .whl]

Run it here (it downloads with pip); prints each wheel and the total size.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

#: packages the GPU machine lacks, pinned where the project pins them (pycocotools, for COCO
#: labels only, is left out: plan arms export YOLO-OBB)
PACKAGES = ("shapely==2.2.0", "trimesh", "open3d-cpu==0.20.0", "isal",
            "ultralytics==8.4.190", "ultralytics-thop==2.2.3")
PLATFORMS = ("manylinux_2_35_x86_64", "manylinux_2_31_x86_64", "manylinux_2_28_x86_64",
             "manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")
#: parts of the open3d wheel left out (never imported by aerial-synth)
OPEN3D_DROP = ("open3d/resources/", "open3d/open3d_tf_ops.so", "open3d/open3d_torch_ops.so",
               "open3d/_ml3d/", "open3d/examples/", "open3d/labextension/", "open3d/agent_skills/")


def download(out: Path, python: str = "3.12") -> None:
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--python-version",
           python, "--implementation", "cp", "-d", str(out)]
    for p in PLATFORMS:
        cmd += ["--platform", p]
    subprocess.run(cmd + ["--platform", "any", *PACKAGES], check=True)


def slim(wheel: Path, drop=OPEN3D_DROP) -> Path:
    """``wheel`` without the members under ``drop``, stored with LZMA; RECORD rewritten."""
    tmp = wheel.with_suffix(".slim")
    with zipfile.ZipFile(wheel) as zin, zipfile.ZipFile(tmp, "w", zipfile.ZIP_LZMA) as zout:
        record_name = next(n for n in zin.namelist() if n.endswith(".dist-info/RECORD"))
        rows = []
        for info in zin.infolist():
            name = info.filename
            if name.startswith(drop) or name == record_name:
                continue
            data = zin.read(name)
            zout.writestr(name, data, compress_type=zipfile.ZIP_LZMA)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            rows.append(f"{name},sha256={digest},{len(data)}")
        rows.append(f"{record_name},,")
        zout.writestr(record_name, "\n".join(rows) + "\n")
    tmp.replace(wheel)
    return wheel


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path(".whl"))
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as t:
        download(Path(t))
        for w in sorted(Path(t).glob("*.whl")):
            if w.name.startswith("open3d_cpu-"):
                slim(w)
            w.replace(a.out / w.name)
    total = 0
    for w in sorted(a.out.glob("*.whl")):
        total += w.stat().st_size
        print(f"{w.stat().st_size / 2**20:7.1f} MiB  {w.name}")
    print(f"{total / 2**20:7.1f} MiB in {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
