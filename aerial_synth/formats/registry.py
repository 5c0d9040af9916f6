"""The label-format registry: every format ``aerial-synth export`` can write.

A format is one small object (a :class:`LabelFormat` subclass instance) that says

- its ``name`` (the ``--format`` value, also its top-level folder in the dataset),
- where an image goes (:meth:`LabelFormat.image_path`) and where its per-image label file
  goes (:meth:`LabelFormat.label_path`, ``None`` when the format has none),
- the text of that label file for one image (:meth:`LabelFormat.label_text`, from the
  image's :class:`~aerial_synth.formats.meta.ImageRecord`),
- its per-dataset files (:meth:`LabelFormat.aggregate_files`, e.g. COCO JSON, data.yaml),
  built from every image's record at the end of an export.

The exporter loops over the requested formats and never branches on a name. Adding a format
(DOTA v1.5, MMRotate's, ...) is one new module that defines ``FORMAT = MyFormat()`` plus one
line in :data:`BUILTIN` below. Paths are relative to the dataset root, with ``/`` separators.

This module imports nothing heavy: format modules are imported the first time they are used.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from ..errors import ExportError
from ..registry import Registry

__all__ = [
    "BUILTIN",
    "DatasetInfo",
    "LabelFormat",
    "get",
    "names",
    "parse_names",
    "register",
    "unregister",
]

#: Built-in formats, in the order the exporter handles them: name -> module defining FORMAT.
BUILTIN: dict[str, str] = {
    "dota": "aerial_synth.formats.dota",
    "eagle": "aerial_synth.formats.eagle",
    "yolo-obb": "aerial_synth.formats.yolo_obb",
    "coco": "aerial_synth.formats.coco",
}


@dataclass(frozen=True)
class DatasetInfo:
    """What a format's per-dataset files may need to know about the whole export.

    splits     : split name -> number of images, e.g. {"train": 8, "val": 2}
    categories : class names in class-index order (:data:`~aerial_synth.formats.CATEGORIES`)
    """

    scene: str
    scenario: str
    seed: int
    tool_version: str
    splits: Mapping[str, int]
    categories: tuple[str, ...]


class LabelFormat:
    """Base class of a dataset label format. Subclasses set :attr:`name` and override the
    methods they need; instances must be stateless and picklable (worker processes get them).
    """

    #: ``--format`` value and top-level folder of the dataset ("dota", "yolo-obb", ...)
    name: str = ""
    #: one line for ``--help`` and docs
    description: str = ""

    @property
    def folder(self) -> str:
        """Top-level folder this format owns inside the dataset."""
        return self.name

    def image_path(self, split: str, file_name: str) -> str:
        """Where an image goes, relative to the dataset root."""
        return f"{self.folder}/{split}/images/{file_name}"

    def label_path(self, split: str, name: str) -> str | None:
        """Where the per-image label file goes (None: the format has none)."""
        return None

    def label_text(self, record) -> str | None:
        """Full text of the per-image label file for ``record`` (an ``ImageRecord``)."""
        return None

    def aggregate_files(self, records, info: DatasetInfo) -> dict:
        """Per-dataset files: relative path -> text, or an iterable of text chunks for a file
        too large to hold (written as they come, e.g. from
        :func:`~aerial_synth.io_utils.iter_json`). ``records``: every image's record in
        index order; the exporter passes a lazy sequence that reads them from disk on each
        iteration (``len`` and ``[i]`` work too), so iterate it rather than keep a list. Its
        ``map(fn, split=None)`` yields ``fn(record)`` in index order, on a process pool for a
        large export (``fn`` module-level, see
        :meth:`~aerial_synth.dataset.aggregate.MetaRecords.map`); a plain list has no
        ``map``, so check for it as COCO does."""
        return {}

    def __repr__(self) -> str:
        return f"<label format {self.name!r}>"


REGISTRY = Registry(BUILTIN, attr="FORMAT", noun="format", option="--format", kind="a LabelFormat",
                    is_entry=lambda o: isinstance(o, LabelFormat), error=ExportError)
names = REGISTRY.names
get = REGISTRY.get
unregister = REGISTRY.unregister


def register(fmt: LabelFormat, *, replace: bool = False) -> LabelFormat:
    """Add a format at run time (a plugin, a test). Its name must be a new one-word,
    lower-case name unless ``replace``."""
    n = getattr(fmt, "name", "")
    if isinstance(fmt, LabelFormat) and (not n or any(c.isspace() or c in ",/\\" for c in n)
                                         or n != n.lower() or n.startswith(".")):
        raise ExportError(f"register: expected a lower-case format name without spaces, commas or "
                          f"slashes, got {n!r}")
    return REGISTRY.register(fmt, replace=replace)


def parse_names(value: str | Iterable[str]) -> tuple[str, ...]:
    """A comma list (or sequence) of format names -> the registered names, de-duplicated, in
    registry order. Raises ExportError naming ``--format`` for an empty or unknown entry."""
    if isinstance(value, str):
        items = [f.strip() for f in value.split(",") if f.strip()]
    else:
        items = [str(f).strip() for f in value]
    items = [f.lower() for f in items]
    valid = names()
    if not items:
        raise ExportError(f"--format: expected a comma list of {', '.join(valid)}, got nothing")
    unknown = [f for f in items if f not in valid]
    if unknown:
        raise ExportError(
            f"--format: unknown format {unknown[0]!r}; expected a comma list of {', '.join(valid)}"
        )
    return tuple(f for f in valid if f in items)
