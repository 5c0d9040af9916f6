"""Dataset label formats: pure ``to_lines``/``from_lines`` (COCO: ``to_dict``/``from_dict``)
plus thin ``write``/``read`` wrappers. Column definitions: docs/formats.md."""

from ._common import CATEGORIES, LabelFormatError

FORMATS: tuple[str, ...] = ("dota", "eagle", "yolo-obb", "coco")

__all__ = ["CATEGORIES", "FORMATS", "LabelFormatError"]
