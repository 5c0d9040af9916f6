"""Guards on ``--out`` shared by every writing command.

- :func:`out_lock`: one writer per output. An exclusive ``flock`` on
  ``.<name>.aerial-synth-lock`` beside the output, the same lock file ``export`` takes
  (:func:`aerial_synth.dataset.output.output_lock`), so two runs of any writing command
  into one ``--out`` never replace each other's files: the second is refused in one line.
  The CLI takes it around every command that has ``--out`` (``aerial_synth.cli``), so no
  command can forget it; a command taking it again inside is a no-op (re-entrant within a
  process). The kernel releases the lock when its process dies, so a killed run never
  blocks the next one.
- :func:`remove_dead_temps`: while the lock is held, the temporary folders a killed run
  left beside ``--out`` (``.<name>.*.tmp``, ``.<name>.*.old``) belong to no live run and
  are removed.
- :func:`refuse_out_is_input`: an output that is one of the command's input files (or an
  input folder) is refused before anything is read or written.
- :func:`refuse_here`: a folder output that is ``''``, the current folder or one of its
  parents is refused (a build beside ``--out`` cannot replace the folder one stands in).
- :func:`staged_dir`: a folder output is built in a temporary sibling and put in place only
  when the command succeeds; a failure (a full disk, a name too long, a signal) leaves
  ``--out`` as it was, with nothing half-written.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import OutputError
from .safe_input import shown

__all__ = ["LOCK_SUFFIX", "lock_path", "out_lock", "remove_dead_temps", "refuse_out_is_input",
           "refuse_here", "staged_dir", "INPUT_OPTIONS"]

LOCK_SUFFIX = ".aerial-synth-lock"
#: Lock files the CLI holds around the running command (``out_lock(..., outer=True)``): the
#: command's own out_lock of the same output, inside it, is then a no-op.
_HELD: set[str] = set()

#: argparse destinations that name input files or folders, per the commands that have them.
INPUT_OPTIONS = ("scene", "file", "dir", "labels", "catalog", "real", "synthetic", "gt", "pred",
                 "names", "images", "compare", "scenario", "placement", "config", "traffic")


def lock_path(out) -> Path:
    """The lock file of output ``out``: ``.<name>.aerial-synth-lock`` in its folder."""
    o = Path(os.path.realpath(out))
    return o.parent / f".{o.name}{LOCK_SUFFIX}"


@contextmanager
def out_lock(out, command: str, option: str = "--out", busy: str | None = None,
             error: type = OutputError, outer: bool = False) -> Iterator[None]:
    """Hold the exclusive lock on ``out`` for the body; a second holder is refused with
    one line naming ``option`` (``busy``, raised as ``error``, when given). The lock file is
    removed at the end; export's lock is this one too (dataset/output.py). ``outer``: the
    CLI's lock around a whole command; an out_lock of the same output inside it is a no-op."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - no flock on this platform: no lock
        yield
        return
    if os.fspath(out) == "":
        raise OutputError(f"{option}: expected a path, got ''")
    lock = lock_path(out)
    if str(lock) in _HELD:  # this process holds it already (the CLI took it)
        yield
        return
    missing = []  # folders made for the lock: removed again when the run leaves them empty
    p = lock.parent
    while not os.path.lexists(p) and p.parent != p:
        missing.append(p)
        p = p.parent
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        _remove_empty(missing)
        if os.path.lexists(p) and not os.path.isdir(p):  # a path below a file
            raise OutputError(f"{option} {shown(out)}: expected a folder at {shown(p)}, found a "
                              "file") from None
        raise OutputError(f"{option} {shown(out)}: cannot lock it ({exc.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise error(busy or
                        f"{option} {shown(out)}: another aerial-synth run is writing it right now; "
                        f"wait for it to finish or choose another {option}") from None
        if outer:
            _HELD.add(str(lock))
        try:
            yield
        finally:
            if outer:
                _HELD.discard(str(lock))
            try:
                os.unlink(lock)
            except OSError:
                pass
    finally:
        os.close(fd)
        _remove_empty(missing)


def _remove_empty(folders: list[Path]) -> None:
    """rmdir each of ``folders`` (innermost first) while they are empty."""
    for d in folders:
        try:
            d.rmdir()
        except OSError:
            break


def remove_dead_temps(out, suffixes: tuple[str, ...] = (".tmp", ".old")) -> list[Path]:
    """Remove ``.<name>.*<suffix>`` entries beside ``out`` (call while holding
    :func:`out_lock`: no live run owns them then). Returns what was removed."""
    o = Path(os.path.realpath(out))
    removed = []
    if not o.parent.is_dir():
        return removed
    prefix = f".{o.name}."
    for entry in o.parent.iterdir():
        if entry.name.startswith(prefix) and entry.name.endswith(suffixes) \
                and entry.name != lock_path(o).name:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                try:
                    entry.unlink()
                except OSError:
                    continue
            removed.append(entry)
    return removed


def _same(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def refuse_out_is_input(args: argparse.Namespace) -> None:
    """Refuse ``args.out`` when it names the same file (or folder) as one of the command's
    inputs (``INPUT_OPTIONS``): ``scene show spec.yaml --out spec.yaml`` must not replace
    the spec with a PNG."""
    out = getattr(args, "out", None)
    if not isinstance(out, (str, os.PathLike)) or os.fspath(out) == "" or not os.path.lexists(out):
        return
    for dest in INPUT_OPTIONS:
        val = getattr(args, dest, None)
        vals = val if isinstance(val, (list, tuple)) else [val]
        for v in vals:
            if isinstance(v, (str, os.PathLike)) and os.fspath(v) and _same(out, v):
                opt = dest.upper() if dest in ("scene", "file", "dir") else f"--{dest}"
                raise OutputError(f"--out {shown(out)}: is the input {opt} {shown(v)}; write "
                                  "the output elsewhere")


def refuse_here(out, option: str = "--out") -> Path:
    """Refuse a folder output that is ``''``, the current folder or a folder above it."""
    if os.fspath(out) == "":
        raise OutputError(f"{option}: expected a folder path, got ''")
    real = Path(os.path.realpath(out))
    here = Path(os.path.realpath(os.getcwd()))
    if real == here or real in here.parents:
        raise OutputError(f"{option} {shown(out)}: expected a new folder, got the current folder "
                          "(or one above it); choose a folder name")
    return Path(out)


@contextmanager
def staged_dir(out, option: str = "--out") -> Iterator[Path]:
    """Yield a temporary sibling folder ``.<name>.XXXXXXXX.tmp`` of the folder output
    ``out`` to write into (call while holding :func:`out_lock`). When the body succeeds, a
    new ``out`` is the sibling renamed; into an existing folder, each file written is moved
    in (``os.replace``, files already there that this run did not write are kept). When it
    fails, the sibling and any folder made for it are removed: ``out`` stays as it was."""
    out = Path(out)
    remove_dead_temps(out)  # a killed run's build: no live run owns it under the lock
    missing = []
    p = out.parent
    while not os.path.lexists(p) and p.parent != p:
        missing.append(p)
        p = p.parent
    out.parent.mkdir(parents=True, exist_ok=True)
    name = os.fsdecode(os.fsencode(out.name)[:200])  # the temporary's name within 255 bytes
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".tmp", dir=out.parent))
    try:
        yield tmp
        _publish(tmp, out, option)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        _remove_empty(missing)
        raise


def _publish(tmp: Path, out: Path, option: str) -> None:
    if not os.path.lexists(out):
        os.rename(tmp, out)
        return
    files = sorted(q for q in tmp.rglob("*") if not q.is_dir())
    for f in files:  # every conflict found before the first move
        dst = out / f.relative_to(tmp)
        if os.path.lexists(dst) and (dst.is_symlink() or not dst.is_file()):
            raise OutputError(f"{option} {shown(out)}: {shown(dst)} exists and is not a file")
    for f in files:
        dst = out / f.relative_to(tmp)
        dst.parent.mkdir(parents=True, exist_ok=True)
        os.replace(f, dst)
    shutil.rmtree(tmp, ignore_errors=True)
