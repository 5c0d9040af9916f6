"""Dataset label formats: pure ``to_lines``/``from_lines`` (COCO: ``to_dict``/``from_dict``)
plus thin ``write``/``read`` wrappers, and the registry the exporter loops over
(:mod:`aerial_synth.formats.registry`). Lenient readers for real-world files
(``dota.read_labels``, ``yolo_obb.labels_from_lines``, ``vedai.labels_from_lines``) return
the one label model, :class:`~aerial_synth.formats.labels.ImageLabels`. Column definitions:
docs/formats.md."""

from ..errors import LabelFormatError
from ._common import CATEGORIES
from .labels import ImageLabels
from .registry import BUILTIN, LabelFormat

#: The built-in format names, in export order (the registry may hold more at run time:
#: use ``registry.names()``).
FORMATS: tuple[str, ...] = tuple(BUILTIN)

__all__ = ["CATEGORIES", "FORMATS", "ImageLabels", "LabelFormat", "LabelFormatError"]
