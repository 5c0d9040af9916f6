"""Dataset label formats: pure ``to_lines``/``from_lines`` (COCO: ``to_dict``/``from_dict``)
plus thin ``write``/``read`` wrappers, and the registry the exporter loops over
(:mod:`aerial_synth.formats.registry`). Column definitions: docs/formats.md."""

from ._common import CATEGORIES, LabelFormatError
from .registry import BUILTIN, LabelFormat

#: The built-in format names, in export order (the registry may hold more at run time:
#: use ``registry.names()``).
FORMATS: tuple[str, ...] = tuple(BUILTIN)

__all__ = ["CATEGORIES", "FORMATS", "LabelFormat", "LabelFormatError"]
