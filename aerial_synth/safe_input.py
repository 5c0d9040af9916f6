# size: every guard on reading user input in one module, the only one the guard scan lets read
"""Guards for reading files a hostile user may hand us.

Every reader of user files goes through these, so each limit has one home:

- :func:`quote` shows at most 40 characters of a line, non-printable ones escaped, for
  error messages (a label line may hold anything, even a password file's first line);
- :func:`shown` prints a path whose name holds bytes that are not UTF-8 (``\\xff``) as
  escapes, so neither ``print`` nor OpenCV ever receives undecodable text;
- :func:`load_yaml` / :func:`load_json` parse with a nesting budget (``MAX_DEPTH``) and,
  for YAML, a budget on what anchors and aliases expand to (``MAX_NODES``: a "billion
  laughs" document is refused in milliseconds, before anything walks it);
- :func:`image_header_size` reads width and height from an image file's header, and
  :func:`check_image_pixels` refuses images above OpenCV's decoding limits before any decode;
- :func:`refuse_escaping_link` refuses a file inside an input folder that is a symbolic link
  to somewhere outside it (as glTF buffer URIs that leave their folder are refused);
- :func:`read_bytes` / :func:`read_text` / :func:`load_yaml_file` / :func:`load_json_file`
  read a user's file with all of the above: a regular file (not a FIFO, a device, a link
  loop), at most ``MAX_TEXT_BYTES``, inside the folder it was found in (``root=``: a file found
  automatically, such as a mesh's ``.labels.yaml``, never leads out of its folder);
- :func:`user_regex` compiles a user's regular expression with RE2 (linear time: no
  pattern and no name makes a match backtrack for minutes).

Every module under ``aerial_synth/`` and ``tools/`` reads user files through these
(``tests/foundation/test_guard_scan.py`` fails on a module that parses YAML/JSON, opens a
file or compiles a regular expression it was given in any other way).
"""

from __future__ import annotations

import json
import os
import stat
import struct
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any

from .errors import ConfigError

__all__ = [
    "MAX_DEPTH",
    "MAX_NODES",
    "MAX_IMAGE_PIXELS",
    "MAX_IMAGE_SIDE",
    "QUOTE_CHARS",
    "MAX_COORD_PX",
    "LABEL_GSD_RANGE_M",
    "quote",
    "shown",
    "load_yaml",
    "load_json",
    "check_depth",
    "image_header_size",
    "check_image_pixels",
    "image_file_complete",
    "read_image",
    "decode_image",
    "quiet_native_stderr",
    "cv_text",
    "refuse_escaping_link",
    "input_roots",
    "check_link",
    "class_name",
    "MAX_TEXT_BYTES",
    "MAX_IMAGE_FILE_BYTES",
    "MAX_REPEAT",
    "read_bytes",
    "read_text",
    "load_yaml_file",
    "load_json_file",
    "user_regex",
]

#: Deepest nesting of lists and mappings a YAML or JSON input may have (ours need < 10).
MAX_DEPTH = 100
#: Most values (scalars, lists, mappings) a YAML document may expand to through its aliases.
MAX_NODES = 1_000_000
#: OpenCV's own decoding limits (``CV_IO_MAX_IMAGE_PIXELS``, ``CV_IO_MAX_IMAGE_WIDTH/HEIGHT``).
MAX_IMAGE_PIXELS = 1 << 30
MAX_IMAGE_SIDE = 1 << 20
#: Largest pixel coordinate (absolute) a label or prediction may hold: ten times OpenCV's
#: largest image side. 1e300 passed as "finite" and overflowed in box areas, where numpy's
#: warnings named no file.
MAX_COORD_PX = 1e7
#: The GSD a label's ``gsd:`` header, or a real set's ``--gsd``/``--real-gsd``, may give,
#: metres per pixel: from 0.1 mm (a close-up) to the camera's largest (1 km,
#: :data:`aerial_synth.camera.MAX_GSD_M`). ``gsd:1e300`` made mix's rescaled image (and its
#: tile list) larger than any memory.
LABEL_GSD_RANGE_M = (1e-4, 1000.0)
#: Characters of an input line quoted in an error message.
QUOTE_CHARS = 40
#: Largest text file (YAML, JSON, label rules, a scene mix) read whole into memory.
MAX_TEXT_BYTES = 256 << 20
#: Largest image file read whole into memory before decoding (a 2^30-pixel RGB PNG, stored).
MAX_IMAGE_FILE_BYTES = 4 << 30
#: Largest repetition count ``{n}`` in a user's regular expression (RE2's own limit; RE2
#: would read a larger count as literal text).
MAX_REPEAT = 1000


def quote(text: Any, limit: int = QUOTE_CHARS) -> str:
    """``text`` in quotes for an error message: at most ``limit`` characters of it (then
    ``...``), every non-printable character (control characters, undecodable bytes kept as
    surrogates) escaped, so a message stays one printable line."""
    s = text if isinstance(text, str) else str(text)
    cut = len(s) > limit
    s = s[:limit]
    out = []
    for ch in s:
        if ch.isprintable() and not ("\ud800" <= ch <= "\udfff"):
            out.append("\\'" if ch == "'" else "\\\\" if ch == "\\" else ch)
        elif "\udc80" <= ch <= "\udcff":  # a byte that was not UTF-8 (surrogateescape)
            out.append(f"\\x{ord(ch) - 0xDC00:02x}")
        else:
            out.append(ch.encode("unicode_escape").decode("ascii"))
    return "'" + "".join(out) + ("...'" if cut else "'")


def shown(path: Any) -> str:
    """A path as printable text: bytes of its name that are not UTF-8 (kept by Python as
    lone surrogates, which ``print`` to a UTF-8 stream and OpenCV cannot take) become
    ``\\xNN`` escapes, other non-printable characters ``\\uNNNN``."""
    s = os.fspath(path)
    if isinstance(s, bytes):
        s = os.fsdecode(s)
    if s.isprintable() and not any("\ud800" <= ch <= "\udfff" for ch in s):
        return s
    out = []
    for ch in s:
        if "\udc80" <= ch <= "\udcff":
            out.append(f"\\x{ord(ch) - 0xDC00:02x}")
        elif ch.isprintable() and not ("\ud800" <= ch <= "\udfff"):
            out.append(ch)
        else:
            out.append(ch.encode("unicode_escape", "backslashreplace").decode("ascii"))
    return "".join(out)


# -- YAML and JSON with budgets ------------------------------------------------------------


class _Budget(Exception):
    def __init__(self, what: str):
        super().__init__(what)
        self.what = what


def _loader_class():
    import yaml

    class BudgetLoader(yaml.SafeLoader):
        """SafeLoader that counts nesting while composing and refuses documents whose
        aliases expand to more than ``MAX_NODES`` values or that refer to themselves."""

        max_depth = MAX_DEPTH
        max_nodes = MAX_NODES

        def __init__(self, stream):
            super().__init__(stream)
            self._depth = 0

        def compose_node(self, parent, index):
            self._depth += 1
            try:
                if self._depth > self.max_depth:
                    raise _Budget(f"nesting at most {self.max_depth} deep, got deeper "
                                  f"(line {self.peek_event().start_mark.line + 1})")
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1

        def compose_document(self):
            node = super().compose_document()
            _expanded_size(node, self.max_nodes)
            return node

        def construct_mapping(self, node, deep=False):
            _refuse_duplicate_keys(self, node)
            return super().construct_mapping(node, deep=deep)

    return BudgetLoader


_LOADER = None


def _expanded_size(root, budget: int) -> int:
    """Values the node graph ``root`` stands for once every alias is expanded (each
    shared node counted as often as it is referred to). Iterative; refuses cycles."""
    from yaml.nodes import MappingNode, SequenceNode

    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        k = id(node)
        if done:
            on_path.discard(k)
            kids = _children(node, SequenceNode, MappingNode)
            total = 1 + sum(size[id(c)] for c in kids)
            if total > budget:
                raise _Budget(f"aliases that expand to at most {budget:,} values, got more "
                              "(a document that multiplies itself)")
            size[k] = total
            continue
        if k in size:
            continue
        if k in on_path:
            raise _Budget("no alias that refers to the list or mapping it is in, got one")
        on_path.add(k)
        stack.append((node, True))
        for c in _children(node, SequenceNode, MappingNode):
            if id(c) not in size:
                stack.append((c, False))
    return size[id(root)]


def _refuse_duplicate_keys(loader, node) -> None:
    """A mapping that names one key twice (PyYAML keeps the last silently) is refused; the
    keys a ``<<`` merge brings in may be overridden, as YAML intends."""
    from yaml.nodes import ScalarNode

    seen: dict = {}
    for key_node, _ in node.value:
        if not isinstance(key_node, ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node)
        try:
            hash(key)
        except TypeError:
            continue
        if (type(key), key) in seen:
            raise _Budget(f"each key once in a mapping, got {quote(key_node.value)} twice "
                          f"(lines {seen[(type(key), key)]} and {key_node.start_mark.line + 1})")
        seen[(type(key), key)] = key_node.start_mark.line + 1


def _children(node, SequenceNode, MappingNode) -> list:
    if isinstance(node, SequenceNode):
        return list(node.value)
    if isinstance(node, MappingNode):
        return [x for kv in node.value for x in kv]
    return []


def _flow_too_deep(text: str, limit: int) -> int:
    """The line where ``[`` / ``{`` brackets outside quotes and comments nest deeper than
    ``limit``, or 0. One linear pass; it may count a bracket PyYAML reads as text (in a
    plain scalar), never misses a real one."""
    depth = 0
    line = 1
    quote_ch = ""
    comment = False
    prev = " "
    for ch in text:
        if ch == "\n":
            line += 1
            comment = False
            if quote_ch == "'":  # a single-quoted scalar may span lines; keep it
                pass
        elif comment:
            pass
        elif quote_ch:
            if ch == quote_ch and not (quote_ch == '"' and prev == "\\"):
                quote_ch = ""
        elif ch in "'\"" and (prev in " \t[{,:" or prev == "\n"):
            quote_ch = ch
        elif ch == "#" and prev in " \t\n":
            comment = True
        elif ch in "[{":
            depth += 1
            if depth > limit:
                return line
        elif ch in "]}":
            depth = max(0, depth - 1)
        prev = ch
    return 0


def load_yaml(text: str, where: str, error: type[Exception] = ConfigError) -> Any:
    """``yaml.safe_load(text)`` within the nesting and alias budgets. A document that is not
    YAML or is over a budget raises ``error`` with one line starting with ``where``."""
    import yaml

    global _LOADER
    if _LOADER is None:
        _LOADER = _loader_class()
    line = _flow_too_deep(text, MAX_DEPTH)
    if line:  # PyYAML's scanner would spend ~1 s on 1,000 open brackets before the composer
        raise error(f"{where}: expected YAML with nesting at most {MAX_DEPTH} deep, got deeper "
                    f"(line {line})")
    try:
        return yaml.load(text, Loader=_LOADER)  # noqa: S506 - a SafeLoader subclass
    except _Budget as exc:
        raise error(f"{where}: expected YAML with {exc.what}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
        at = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        raise error(f"{where}: broken YAML ({at}{quote(problem, 80)[1:-1]})") from None
    except (RecursionError, ValueError, TypeError, OverflowError) as exc:
        raise error(f"{where}: broken YAML ({type(exc).__name__})") from None


def check_depth(obj: Any, where: str, error: type[Exception] = ConfigError,
                max_depth: int = MAX_DEPTH) -> Any:
    """Refuse a parsed document nested deeper than ``max_depth`` (iterative walk)."""
    stack = [(obj, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, dict):
            kids = v.values()
        elif isinstance(v, (list, tuple)):
            kids = v
        else:
            continue
        if d > max_depth:
            raise error(f"{where}: expected nesting at most {max_depth} deep, got deeper")
        stack.extend((k, d + 1) for k in kids)
    return obj


def load_json(text: str | bytes, where: str, error: type[Exception] = ConfigError) -> Any:
    """``json.loads(text)`` within the nesting budget; one line naming ``where`` otherwise."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{where}:{exc.lineno}: expected JSON, {exc.msg}") from None
    except RecursionError:
        raise error(f"{where}: expected JSON nested at most {MAX_DEPTH} deep, got deeper") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise error(f"{where}: expected JSON ({type(exc).__name__})") from None
    return check_depth(data, where, error)


# -- image headers ---------------------------------------------------------------------------


def image_header_size(path) -> tuple[int, int] | None:
    """(width, height) from the header of a PNG, JPEG, BMP, GIF, TIFF or WebP file without
    decoding it; None when the header is not one of these or is cut short. OSError when the
    file cannot be read."""
    with open(path, "rb") as fh:
        head = fh.read(32)
        if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR" and len(head) >= 24:
            return struct.unpack(">II", head[16:24])
        if head[:2] == b"\xff\xd8":
            return _jpeg_size(fh)
        if head[:2] == b"BM" and len(head) >= 26:
            w, h = struct.unpack("<ii", head[18:26])
            return abs(w), abs(h)
        if head[:6] in (b"GIF87a", b"GIF89a") and len(head) >= 10:
            return struct.unpack("<HH", head[6:10])
        if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
            return _webp_size(head, fh)
        if head[:4] in (b"II*\x00", b"MM\x00*"):
            return _tiff_size(fh, head[:2])
    return None


def _jpeg_size(fh) -> tuple[int, int] | None:
    fh.seek(2)
    for _ in range(100_000):  # a bounded walk over the segments
        b = fh.read(1)
        while b and b != b"\xff":
            b = fh.read(1)
        while b == b"\xff":
            b = fh.read(1)
        if not b:
            return None
        marker = b[0]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            continue
        seg = fh.read(2)
        if len(seg) < 2:
            return None
        n = struct.unpack(">H", seg)[0]
        if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
            data = fh.read(5)
            if len(data) < 5:
                return None
            h, w = struct.unpack(">HH", data[1:5])
            return int(w), int(h)
        if n < 2:
            return None
        fh.seek(n - 2, os.SEEK_CUR)
    return None


def _webp_size(head: bytes, fh) -> tuple[int, int] | None:
    fh.seek(12)
    chunk = fh.read(20)
    if chunk[:4] == b"VP8X" and len(chunk) >= 18:
        w = int.from_bytes(chunk[12:15], "little") + 1
        h = int.from_bytes(chunk[15:18], "little") + 1
        return w, h
    if chunk[:4] == b"VP8L" and len(chunk) >= 13:
        b = int.from_bytes(chunk[9:13], "little")
        return (b & 0x3FFF) + 1, ((b >> 14) & 0x3FFF) + 1
    if chunk[:4] == b"VP8 " and len(chunk) >= 20:
        w, h = struct.unpack("<HH", chunk[16:20])
        return w & 0x3FFF, h & 0x3FFF
    return None


def _tiff_size(fh, order: bytes) -> tuple[int, int] | None:
    e = "<" if order == b"II" else ">"
    fh.seek(4)
    off = struct.unpack(e + "I", fh.read(4))[0]
    fh.seek(off)
    raw = fh.read(2)
    if len(raw) < 2:
        return None
    n = min(struct.unpack(e + "H", raw)[0], 4096)
    w = h = None
    for _ in range(n):
        ent = fh.read(12)
        if len(ent) < 12:
            break
        tag, typ = struct.unpack(e + "HH", ent[:4])
        val = struct.unpack(e + "H", ent[8:10])[0] if typ == 3 else struct.unpack(e + "I", ent[8:12])[0]
        if tag == 256:
            w = val
        elif tag == 257:
            h = val
    return (w, h) if w is not None and h is not None else None


def check_image_pixels(path, error: type[Exception] = ConfigError,
                       where: str | None = None) -> tuple[int, int] | None:
    """Refuse an image whose header declares more pixels than OpenCV decodes (a 100,000 x
    100,000 PNG would make ``cv2.imread`` fail with its own messages, or take all memory).
    Returns the header's (width, height), or None for a header it does not know."""
    label = where if where is not None else shown(path)
    check_link(path, error)
    try:
        size = image_header_size(path)
    except OSError as exc:
        raise error(f"{label}: cannot read the image ({exc.strerror or type(exc).__name__})") from None
    if size is None:
        return None
    w, h = int(size[0]), int(size[1])
    if w <= 0 or h <= 0:
        raise error(f"{label}: expected an image of at least 1 x 1 px, its header says {w} x {h}")
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        raise error(f"{label}: expected an image of at most {MAX_IMAGE_PIXELS:,} pixels and "
                    f"{MAX_IMAGE_SIDE:,} px a side (OpenCV's limit), its header says {w} x {h}")
    return w, h


_PNG_END = b"IEND\xaeB`\x82"


def image_file_complete(path, size_wh: tuple[int, int] | None = None) -> bool:
    """False when ``path`` is a PNG or JPEG cut short (no header, or no ``IEND`` chunk /
    end-of-image marker at its end), or when its header does not declare ``size_wh`` (if
    given). Other image types are judged by their header size only. Two small reads: a
    check for every file a resumed export keeps, where a file cut short (a full disk, a copy
    interrupted) must be made again, and before any decode of a user's image."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
            fh.seek(0, os.SEEK_END)
            n = fh.tell()
            fh.seek(max(0, n - 16))
            tail = fh.read()
        size = image_header_size(path)
    except OSError:
        return False
    if size_wh is not None and (size is None or tuple(int(v) for v in size) != tuple(size_wh)):
        return False
    if head.startswith(b"\x89PNG"):
        return size is not None and tail.endswith(_PNG_END)
    if head.startswith(b"\xff\xd8"):
        return size is not None and tail.rstrip(b"\x00").endswith(b"\xff\xd9")
    return True


def read_image(path, flags: int | None = None, error: type[Exception] = ConfigError,
               where: str | None = None):
    """Decode an image file with OpenCV, safely: the header's size is checked against
    OpenCV's limits first (:func:`check_image_pixels`), and the bytes are read by Python
    and handed to ``cv2.imdecode``, so OpenCV never receives a file name (a name with bytes
    that are not UTF-8 crashed it). Raises ``error`` naming the file when it cannot be
    decoded."""
    import cv2
    import numpy as np

    label = where if where is not None else shown(path)
    check_image_pixels(path, error, label)
    if not image_file_complete(path):  # libpng would decode the half it has, with grey rows
        raise error(f"{label}: truncated or damaged image (its header or end is missing)")
    try:
        data = np.fromfile(os.fspath(path), np.uint8)
    except OSError as exc:
        raise error(f"{label}: cannot read the image ({exc.strerror or type(exc).__name__})") from None
    img = decode_image(data, cv2.IMREAD_UNCHANGED if flags is None else flags)
    if img is None:
        raise error(f"{label}: expected an image, cannot decode it")
    return img


@contextmanager
def quiet_native_stderr() -> Iterator[None]:
    """Send what native code writes to file descriptor 2 (libpng's ``libpng error: ...``,
    OpenCV's ``[ERROR:0@..]`` lines) to /dev/null for the body: a damaged image then gives
    our one line only. Python's own ``sys.stderr`` is flushed first and restored after."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, AttributeError, ValueError):
        yield
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 2)
        finally:
            os.close(null)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def decode_image(data, flags: int):
    """``cv2.imdecode(data, flags)`` with the decoders' own messages silenced; None when
    the bytes are not a decodable image."""
    import cv2

    if data is None or len(data) == 0:
        return None
    with quiet_native_stderr():
        try:
            return cv2.imdecode(data, flags)
        except cv2.error:
            return None


def cv_text(text: Any) -> str:
    """Text OpenCV's Hershey fonts can draw: ASCII only (every other character, and any
    undecodable byte kept as a surrogate, becomes ``?``)."""
    return "".join(ch if " " <= ch <= "~" else "?" for ch in str(text))


# -- links out of an input folder ------------------------------------------------------------


def refuse_escaping_link(path, root, option: str, error: type[Exception] = ConfigError) -> Path:
    """Refuse ``path`` (a file found in the input folder ``root``) when it is, or lies below,
    a symbolic link whose target is outside ``root``. The message names the link, never the
    target's content."""
    p = Path(path)
    try:
        real = Path(os.path.realpath(p))
        base = Path(os.path.realpath(root))
    except (OSError, ValueError):
        raise error(f"{option} {shown(p)}: cannot resolve the path") from None
    if real != base and base not in real.parents:
        raise error(f"{option} {shown(p)}: a symbolic link to {shown(real)}, outside the input "
                    f"folder {shown(root)}; copy the file in instead")
    return p


#: The input folders of the running command (set by the CLI): files found below one of them
#: must not be links to a place outside it.
_INPUT_ROOTS: ContextVar[tuple[str, ...]] = ContextVar("aerial_synth_input_roots", default=())


@contextmanager
def input_roots(paths: Iterable) -> Iterator[None]:
    """For the body, every file read below one of the folders ``paths`` (the command's input
    folders) is checked by :func:`check_link`. Paths that are not folders are ignored."""
    roots = []
    for p in paths:
        try:
            if p is not None and os.fspath(p) and os.path.isdir(p):
                roots.append(os.path.abspath(p))
        except (TypeError, ValueError, OSError):
            continue
    token = _INPUT_ROOTS.set(tuple(roots))
    try:
        yield
    finally:
        _INPUT_ROOTS.reset(token)


def _below(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


def check_link(path, error: type[Exception] = ConfigError) -> None:
    """Refuse ``path`` when it is not a regular file (a FIFO would block the read forever, a
    device could be endless) or when it lies below one of the command's input folders
    (:func:`input_roots`) but resolves, through a symbolic link, to a place outside it: a
    label file linked to ``/etc/shadow`` is refused by name and its content never read."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        mode = None  # missing or unreadable: the read that follows names it
    if mode is not None and not stat.S_ISREG(mode):
        what = ("a folder" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else
                "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
        raise error(f"{shown(path)}: expected a regular file, found {what}")
    roots = _INPUT_ROOTS.get()
    if not roots:
        return
    a = os.path.abspath(path)
    for r in roots:
        if _below(a, r):
            if not _below(os.path.realpath(a), os.path.realpath(r)):
                raise error(f"{shown(path)}: a symbolic link to {shown(os.path.realpath(a))}, outside "
                            f"the input folder {shown(r)}; copy the file in instead")
            return


def class_name(text: Any, where: str, error: type[Exception] = ConfigError) -> str:
    """A class name as a label file holds it: printable text without spaces (undecodable
    bytes of a file name or an argument are refused here, not at the first ``print``)."""
    s = text if isinstance(text, str) else None
    if not s or not s.isprintable() or any(ch.isspace() or "\ud800" <= ch <= "\udfff" for ch in s):
        raise error(f"{where}: expected a class name of printable UTF-8 text without spaces, "
                    f"got {quote(s if s is not None else repr(text))}")
    return s


# -- reading a user's file -------------------------------------------------------------------


def _open_error(exc: OSError) -> str:
    import errno

    if exc.errno == errno.ENOENT:
        return "file not found"
    if exc.errno == errno.ELOOP:
        return "a loop of symbolic links"
    return f"cannot read it ({exc.strerror or type(exc).__name__})"


def _check_root(path, root, where: str, error: type[Exception]) -> None:
    """A file found automatically in ``root`` must resolve inside ``root``."""
    try:
        real = os.path.realpath(path)
        base = os.path.realpath(root)
    except (OSError, ValueError, RuntimeError):
        raise error(f"{where}: cannot resolve the path") from None
    if not _below(real, base):
        raise error(f"{where}: a symbolic link to a place outside its folder {shown(root)}; "
                    "copy the file in instead")


def read_bytes(path, where: str | None = None, error: type[Exception] = ConfigError, *,
               root=None, max_bytes: int = MAX_TEXT_BYTES) -> bytes:
    """The bytes of the user's file ``path``: refused in one line starting with ``where``
    (default: the path) when it is missing, not a regular file (a FIFO would block forever,
    a device never ends), a link out of an input folder (:func:`check_link`) or out of
    ``root`` (the folder it was found in), or larger than ``max_bytes``. The size is checked
    on the open file, before anything is read."""
    label = where if where is not None else shown(path)
    if root is not None:
        _check_root(path, root, label, error)
    try:
        check_link(path, error)
    except error as exc:  # the same refusal under the caller's label
        msg, head = str(exc), f"{shown(path)}: "
        raise error(f"{label}: {msg[len(head):] if msg.startswith(head) else msg}") from None
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except (OSError, ValueError) as exc:
        raise error(f"{label}: {_open_error(exc) if isinstance(exc, OSError) else 'bad path'}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # swapped in after the check
            raise error(f"{label}: expected a regular file")
        if st.st_size > max_bytes:
            raise error(f"{label}: expected a file of at most {max_bytes >> 20} MiB "
                        f"(aerial-synth's limit for text inputs), got {st.st_size / 2**20:.1f} MiB")
        chunks = []
        total = 0
        while True:
            b = os.read(fd, 1 << 20)
            if not b:
                break
            total += len(b)
            if total > max_bytes:
                raise error(f"{label}: expected a file of at most {max_bytes >> 20} MiB "
                            "(aerial-synth's limit for text inputs), it grew while read")
            chunks.append(b)
        return b"".join(chunks)
    except OSError as exc:
        raise error(f"{label}: {_open_error(exc)}") from None
    finally:
        os.close(fd)


def read_text(path, where: str | None = None, error: type[Exception] = ConfigError, *,
              root=None, max_bytes: int = MAX_TEXT_BYTES) -> str:
    """:func:`read_bytes` decoded as UTF-8 (one line naming the file otherwise)."""
    label = where if where is not None else shown(path)
    data = read_bytes(path, label, error, root=root, max_bytes=max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{label}: expected UTF-8 text, got byte 0x{data[exc.start]:02x} at "
                    f"offset {exc.start}") from None


def load_yaml_file(path, where: str | None = None, error: type[Exception] = ConfigError, *,
                   root=None) -> Any:
    """:func:`load_yaml` of the user's file ``path`` read by :func:`read_text`. Every YAML
    file the project reads is a mapping or a list (or empty): a document that is one scalar
    (the first line of a password file reads as one) is refused by its type, its text never
    quoted."""
    label = where if where is not None else shown(path)
    data = load_yaml(read_text(path, label, error, root=root), label, error)
    if data is not None and not isinstance(data, (dict, list)):
        kind = "text" if isinstance(data, str) else f"a single {type(data).__name__}"
        raise error(f"{label}: expected a YAML mapping or list, got {kind} (not shown)")
    return data


def load_json_file(path, where: str | None = None, error: type[Exception] = ConfigError, *,
                   root=None) -> Any:
    """:func:`load_json` of the user's file ``path`` read by :func:`read_bytes`."""
    label = where if where is not None else shown(path)
    return load_json(read_bytes(path, label, error, root=root), label, error)


def user_regex(pattern: Any, option: str, error: type[Exception] = ConfigError, *,
               ignore_case: bool = False):
    """A user's regular expression compiled by RE2 (``google-re2``): matching takes time
    linear in the text, so ``(a+)+$`` against ``aaa...a!`` is as quick as any other
    pattern. Python syntax RE2 lacks (back-references, look-around) and repetition counts
    above ``MAX_REPEAT`` are refused in one line naming ``option``."""
    import re

    if not isinstance(pattern, str):
        raise error(f"{option}: expected a regular expression (text), got {quote(repr(pattern))}")
    if any("\ud800" <= ch <= "\udfff" for ch in pattern) or "\x00" in pattern:
        raise error(f"{option}: expected a regular expression of UTF-8 text, got {quote(pattern)}")
    for m in re.finditer(r"\{\s*(\d+)\s*(?:,\s*(\d*)\s*)?\}", pattern):
        if any(g and int(g) > MAX_REPEAT for g in m.groups()):
            raise error(f"{option}: expected repetition counts of at most {MAX_REPEAT}, got "
                        f"{quote(m.group(0))} in {quote(pattern)}")
    import re2

    opts = re2.Options()
    opts.case_sensitive = not ignore_case
    opts.log_errors = False
    try:
        return re2.compile(pattern, opts)
    except (re2.error, ValueError, TypeError, OverflowError) as exc:
        why = exc.args[0] if exc.args else exc
        why = why.decode("utf-8", "replace") if isinstance(why, bytes) else str(why)
        raise error(f"{option}: expected a regular expression RE2 accepts (no back-references "
                    f"or look-around), got {quote(pattern)} ({quote(why, 80)[1:-1]})") from None
