"""The export's output folder: what to do with ``--out``, where to build, and the final swap.

A new export, or one that replaces a dataset (``--force``), is built in a hidden sibling
folder ``.<name>.aerial-synth-partial`` next to ``--out`` and moved into place only when it
is complete, so

- an existing dataset stays intact, byte for byte, until the new one has been written in
  full; if the new run fails or is killed, the old one is still there;
- ``--out`` appears only once complete; a killed export leaves its partial folder, which
  ``--resume`` finishes (and a rerun without ``--resume`` refuses to silently discard);
- an export that fails before finishing any image removes its partial folder again.

The swap: ``--out`` missing -> one rename; ``--out`` an empty folder -> the entries are
moved into it (the manifest last). ``--out`` holding a dataset -> it is
renamed to ``.<name>.aerial-synth-old``, the build is renamed to ``--out``, the user's own
files in the old dataset (anything that is not a dataset file or a format folder) are moved
across, and the old dataset is deleted. A kill between the two renames leaves the complete
new dataset in the partial folder and the old one in the ``-old`` folder: ``--resume``
finishes the move (and retires the old folder the same way). ``--force`` into a folder that is not a
dataset moves the new dataset's entries in beside the files already there (and refuses up
front if one of its names is taken).
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from ..errors import ExportError, OutputError
from ..io_utils import check_output_dir
from ..out_guard import LOCK_SUFFIX, out_lock
from ..render.config import RenderOptions
from .config import RENDER_KEYS, ExportConfig
from .layout import owned_names
from .manifest import read_manifest

__all__ = ["PARTIAL_SUFFIX", "OutputPlan", "partial_dir", "plan_output", "output_lock",
           "prepare_build", "discard_build", "finish_output", "remove_stray_temps"]

PARTIAL_SUFFIX = ".aerial-synth-partial"
OLD_SUFFIX = ".aerial-synth-old"


def partial_dir(out: Path) -> Path:
    out = Path(os.path.realpath(out))
    return out.parent / f".{out.name}{PARTIAL_SUFFIX}"


@dataclass(frozen=True)
class OutputPlan:
    """out   : the final dataset folder (absolute)
    build    : where this run writes (the partial sibling, or ``out`` for an in-place resume)
    mode     : "new" (fresh build), "resume" (finish ``build``) or "overwrite"
    into     : what ``out`` is now: "missing", "empty", "dataset" or "foreign"
    fresh    : ``build`` must be (re)created empty before writing
    """

    out: Path
    build: Path
    mode: str
    into: str
    fresh: bool

    @property
    def in_place(self) -> bool:
        return self.build == self.out


def _dir_state(p: Path) -> str:
    if not p.exists():
        return "missing"
    if not any(p.iterdir()):
        return "empty"
    return "dataset" if read_manifest(p) is not None else "foreign"


def _param_diff(old: dict | None, new: dict) -> list[str]:
    """The parameters a manifest's ``old`` and this run's ``new`` (``ExportConfig.to_dict``)
    disagree on. A render option an earlier version wrote at its default (an
    ``ExportConfig(render_preset="full")`` made in Python) matches its absence."""
    old = dict(old) if isinstance(old, dict) else {}
    default = RenderOptions()
    for key, name in RENDER_KEYS.items():
        if key in old and old[key] == getattr(default, name):
            del old[key]
    return sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))


def plan_output(cfg: ExportConfig, out_dir, resume: bool, force: bool) -> OutputPlan:
    """Decide what this export does with ``--out`` (writes nothing). Raises OutputError /
    ExportError with one line for a folder it must not or cannot use."""
    shown = str(out_dir)
    check_output_dir(out_dir, "--out")
    out = Path(os.path.realpath(out_dir))  # a link to a folder: build beside its target
    if out.parent == out or not out.name:
        raise OutputError(f"--out {shown}: expected a dataset folder, not the file-system root")
    if out.name.endswith((PARTIAL_SUFFIX, OLD_SUFFIX, LOCK_SUFFIX)):
        raise OutputError(f"--out {shown}: that name is reserved for aerial-synth's temporary folders")
    part = partial_dir(out)
    if part.exists() and not part.is_dir():
        raise OutputError(f"--out {shown}: {part} exists and is not a folder; remove it")
    if not os.access(out.parent if out.parent.exists() else _existing_ancestor(out), os.W_OK | os.X_OK):
        raise OutputError(
            f"--out {shown}: the folder {out.parent} is not writable (the export is built "
            "beside --out and moved into place at the end)"
        )
    into = _dir_state(out)
    part_state = _dir_state(part)
    if part_state == "foreign":
        raise OutputError(f"--out {shown}: {part} exists and is not an aerial-synth partial export; "
                          "remove it")
    new = cfg.to_dict()

    if resume and part_state == "dataset":
        diff = _param_diff(read_manifest(part).get("parameters"), new)
        if not diff:
            return OutputPlan(out, part, "resume", into, fresh=False)
        if not force:
            raise ExportError(
                f"--resume {shown}: the interrupted export was started with other parameters "
                f"({', '.join(diff)}); give the same parameters or pass --force to start over"
            )
        return _fresh(out, part, into, shown)
    if part_state == "dataset" and not force:
        raise ExportError(
            f"--out {shown}: an interrupted export of this folder is in {part}; pass --resume "
            "to finish it or --force to start over"
        )
    if into in ("missing", "empty"):
        return OutputPlan(out, part, "new", into, fresh=True)
    if into == "foreign":
        if not force:
            raise ExportError(
                f"--out {shown}: folder exists, is not empty and is not an aerial-synth dataset "
                "(no manifest.json); choose another folder or pass --force"
            )
        taken = sorted(n for n in owned_names() if (out / n).exists() or (out / n).is_symlink())
        if taken:
            raise ExportError(
                f"--out {shown}: --force would write beside files that are not an aerial-synth "
                f"dataset, but {taken[0]!r} is already there; move it away or choose another folder"
            )
        return OutputPlan(out, part, "new", into, fresh=True)
    # ``out`` holds a dataset
    if resume:
        diff = _param_diff(read_manifest(out).get("parameters"), new)
        if not diff:
            return OutputPlan(out, out, "resume", into, fresh=False)
        if not force:
            raise ExportError(
                f"--resume {shown}: the dataset was made with other parameters ({', '.join(diff)}); "
                "give the same parameters or pass --force to overwrite"
            )
        return _fresh(out, part, into, shown)
    if not force:
        raise ExportError(
            f"--out {shown}: an aerial-synth dataset already exists there; pass --resume to finish "
            "it or --force to overwrite it"
        )
    return _fresh(out, part, into, shown)


def _fresh(out: Path, part: Path, into: str, shown: str) -> OutputPlan:
    return OutputPlan(out, part, "overwrite" if into == "dataset" else "new", into, fresh=True)


def output_lock(out_dir):
    """Hold an exclusive lock on ``--out`` for an export's writing phase, so a second export
    into the same folder (or its partial build) is refused in one line instead of mixing its
    files in: :func:`aerial_synth.out_guard.out_lock` (``flock`` on
    ``.<name>.aerial-synth-lock`` beside ``--out``, released by the kernel if the process
    dies; the file is removed at the end), the lock every writing command takes."""
    return out_lock(out_dir, "export", busy=f"--out {out_dir}: another aerial-synth export is writing "
                    "this folder right now; wait for it to finish or choose another folder",
                    error=ExportError)


def _existing_ancestor(p: Path) -> Path:
    p = Path(p)
    while not p.exists() and p.parent != p:
        p = p.parent
    return p


def prepare_build(plan: OutputPlan) -> None:
    """Create the build folder (emptying an old partial one first when ``plan.fresh``)."""
    if plan.fresh and plan.build.exists():
        shutil.rmtree(plan.build)
    plan.build.mkdir(parents=True, exist_ok=True)


def discard_build(plan: OutputPlan) -> None:
    """Remove a fresh build that failed before it finished any image."""
    if plan.fresh and not plan.in_place and plan.build.exists():
        shutil.rmtree(plan.build, ignore_errors=True)


def _retire_old(old: Path, out: Path) -> None:
    """Delete a replaced dataset ``old`` after moving the user's own entries (anything that
    is not a dataset file or a format folder) into ``out``."""
    if not old.exists():
        return
    owned = set(owned_names())
    for entry in sorted(os.listdir(old)):
        if entry not in owned and not (out / entry).exists() and not (out / entry).is_symlink():
            os.rename(old / entry, out / entry)
    shutil.rmtree(old)


def finish_output(plan: OutputPlan) -> None:
    """Move a finished build into ``plan.out`` (see the module docstring)."""
    if plan.in_place:
        return
    out, build = plan.out, plan.build
    old = out.parent / f".{out.name}{OLD_SUFFIX}"
    state = _dir_state(out)
    if state in ("empty", "foreign"):
        # Keep the user's folder itself (its inode, mode, owner; it may be the shell's working
        # folder): move the entries in, the manifest last, so it is a dataset only when whole.
        entries = sorted(os.listdir(build), key=lambda e: (e == "manifest.json", e))
        for entry in entries:
            os.rename(build / entry, out / entry)
        build.rmdir()
        _retire_old(old, out)
        return
    if state == "dataset":
        if old.exists():  # left by a replacement interrupted after its first rename
            _retire_old(old, out)
        os.rename(out, old)  # from here until the next rename, --out is missing (< 1 ms)
    os.rename(build, out)
    _retire_old(old, out)


def remove_stray_temps(build: Path) -> None:
    """Delete temporary files a killed export left behind (``.<name>.*.tmp`` / ``.lnk``)."""
    build = Path(build)
    for name in owned_names():
        p = build / name
        if p.is_dir():
            for f in p.rglob(".*"):
                if f.is_file() and f.name.endswith((".tmp", ".lnk")):
                    f.unlink()
    for f in build.glob(".*.tmp"):
        f.unlink()
