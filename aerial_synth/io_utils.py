"""Atomic file writes and output-path checks.

Writes go to a temporary name in the same folder, then ``os.replace``. Nothing that exists and
is not a regular file (a device node, a FIFO, a socket, a folder) is ever replaced: the
``check_output_*`` functions refuse such paths up front, in one line naming the option, and
:func:`atomic_write_bytes` refuses them again at the moment of writing.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from .errors import OutputError

__all__ = [
    "RawJson",
    "replace_dir",
    "StreamedList",
    "atomic_write_bytes",
    "atomic_write_chunks",
    "atomic_write_text",
    "atomic_write_json",
    "dumps_json",
    "iter_json",
    "check_output_file",
    "check_output_dir",
    "is_inside",
]


def _kind(st_mode: int) -> str:
    if stat.S_ISDIR(st_mode):
        return "a folder"
    if stat.S_ISCHR(st_mode):
        return "a character device"
    if stat.S_ISBLK(st_mode):
        return "a block device"
    if stat.S_ISFIFO(st_mode):
        return "a FIFO"
    if stat.S_ISSOCK(st_mode):
        return "a socket"
    return "not a regular file"


def _check_parents(path: Path, option: str) -> None:
    """The nearest existing ancestor of ``path`` must be a writable folder."""
    parent = path.parent
    while True:
        try:
            st = os.stat(parent)
        except FileNotFoundError:
            if parent.parent == parent:
                break
            parent = parent.parent
            continue
        except NotADirectoryError:  # an ancestor further up is a file
            parent = parent.parent
            continue
        except OSError as exc:
            raise OutputError(f"{option} {path}: cannot use {parent}: {exc.strerror}") from None
        if not stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{option} {path}: expected a folder at {parent}, found a file")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise OutputError(f"{option} {path}: folder {parent} is not writable")
        return


def _stat_output(path, option: str, what: str):
    """(Path, os.stat_result or None when nothing is there yet); one line for odd paths.
    A path below a file also gives None: :func:`_check_parents` reports it."""
    if os.fspath(path) == "":  # Path("") would silently mean "."
        raise OutputError(f"{option}: expected {what}, got ''")
    path = Path(path)
    try:
        return path, os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return path, None
    except OSError as exc:
        raise OutputError(f"{option} {path}: cannot use it: {exc.strerror}") from None


def check_output_file(path: str | os.PathLike, option: str = "--out") -> Path:
    """Refuse an output file path that cannot be written safely; returns it as a Path.

    Refused: an existing path that is not a regular file (device, FIFO, socket, folder),
    a path below a file, or a path whose nearest existing folder is not writable.
    """
    path, st = _stat_output(path, option, "a file path")
    if st is not None:
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(
                f"{option} {path}: expected a regular file to write, found {_kind(st.st_mode)}"
            )
        if not os.access(path, os.W_OK):
            raise OutputError(f"{option} {path}: the existing file is not writable")
    _check_parents(path, option)
    return path


def check_output_dir(path: str | os.PathLike, option: str = "--out") -> Path:
    """Refuse an output folder path that is not a folder or cannot be created/written."""
    path, st = _stat_output(path, option, "a folder path")
    real = Path(os.path.realpath(path))
    if real.parent == real:
        raise OutputError(f"{option} {path}: expected a folder to write into, not the file-system root")
    if st is not None:
        if not stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{option} {path}: expected a folder, found {_kind(st.st_mode)}"
                              if not stat.S_ISREG(st.st_mode)
                              else f"{option} {path}: expected a folder, found a file")
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError(f"{option} {path}: folder is not writable")
        return path
    _check_parents(path, option)
    return path


def is_inside(child: str | os.PathLike, parent: str | os.PathLike) -> bool:
    """True when ``child`` is ``parent`` or lies below it (after resolving links). A loop of
    links resolves as far as it goes (``os.path.realpath``; ``Path.resolve`` raised
    RuntimeError, a traceback for ``stats loop/x``)."""
    c = Path(os.path.realpath(child))
    p = Path(os.path.realpath(parent))
    return c == p or p in c.parents


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file in the same folder + ``os.replace``)."""
    return atomic_write_chunks(path, (data,))


def atomic_write_chunks(path: str | os.PathLike, chunks: Iterable[bytes | str]) -> Path:
    """Write the concatenation of ``chunks`` (bytes, or str written as UTF-8) to ``path``
    atomically, holding one chunk at a time: a file larger than memory, e.g. the COCO JSON
    of a 100,000-image export. An error while the chunks are made leaves the old file (or
    none) and no temporary."""
    path = Path(path)
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise OutputError(f"{path}: expected a regular file to replace, found {_kind(st.st_mode)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    # the temporary name: ".<name>.XXXXXXXX.tmp", the name cut to fit the 255-byte limit
    fd, tmp = tempfile.mkstemp(prefix=f".{os.fsdecode(os.fsencode(path.name)[:200])}.",
                               suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual file mode
        with os.fdopen(fd, "wb", buffering=1 << 20) as fh:
            for chunk in chunks:
                fh.write(chunk.encode("utf-8") if isinstance(chunk, str) else chunk)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def dumps_json(obj: Any) -> str:
    """Deterministic JSON text (sorted keys, 2-space indent, trailing newline)."""
    return json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n"


class StreamedList:
    """A JSON list whose items come from an iterable, consumed once by :func:`iter_json` (so
    the list is never held whole). Allowed as a value of a dict (at any depth of dicts) or
    at the top level."""

    __slots__ = ("items",)

    def __init__(self, items: Iterable):
        self.items = items


class RawJson:
    """A value whose JSON text is given: ``text`` exactly as :func:`dumps_json` would print
    the value at the top level (without its trailing newline). :func:`iter_json` indents it
    for its depth. For a producer that formats its items faster than ``json`` (a fixed
    schema) and checks the bytes against ``json`` in its tests."""

    __slots__ = ("text",)

    def __init__(self, text: str):
        self.text = text


def iter_json(obj: Any) -> Iterator[str]:
    """The text of :func:`dumps_json` (``obj``) in chunks, with every :class:`StreamedList`
    written item by item: the same characters, a bounded amount of memory. The values of a
    dict are serialised in key order, one after the other, so a plain list that a streamed
    one fills as it is consumed may follow it (under a later key)."""
    yield from _json_chunks(obj, 0)
    yield "\n"


def _streams(obj: Any) -> bool:
    return isinstance(obj, StreamedList) or (
        isinstance(obj, dict) and any(_streams(v) for v in obj.values()))


def _json_chunks(obj: Any, level: int) -> Iterator[str]:
    """json.dumps(obj, indent=2, sort_keys=True) as it would print ``level`` deep."""
    pad = "\n" + "  " * (level + 1)
    if isinstance(obj, RawJson):
        yield obj.text.replace("\n", "\n" + "  " * level) if level else obj.text
    elif isinstance(obj, StreamedList):
        first = True
        for item in obj.items:
            yield ("[" if first else ",") + pad
            yield from _json_chunks(item, level + 1)
            first = False
        yield "[]" if first else "\n" + "  " * level + "]"
    elif isinstance(obj, dict) and _streams(obj):
        for j, (k, v) in enumerate(sorted(obj.items())):
            yield ("{" if j == 0 else ",") + pad + json.dumps(k) + ": "
            yield from _json_chunks(v, level + 1)
        yield "\n" + "  " * level + "}"
    else:
        text = json.dumps(obj, indent=2, sort_keys=True, allow_nan=False)
        yield text.replace("\n", "\n" + "  " * level) if level else text


def atomic_write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Write ``obj`` as deterministic JSON to ``path`` atomically."""
    return atomic_write_text(path, dumps_json(obj))


def replace_dir(tmp: Path, out: Path) -> None:
    """Put the finished folder ``tmp`` (a sibling of ``out``) at ``out``. An existing ``out`` is
    renamed aside first (``.NAME.XXXX.old``, what a dead run's cleanup looks for) and removed
    after, so ``out`` is always the old folder or the new one, never a mix."""
    if out.exists():
        trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".old", dir=out.parent))
        os.rename(out, trash / "old")
        os.rename(tmp, out)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.rename(tmp, out)
