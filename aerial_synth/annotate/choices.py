"""The choices of the box options, as enums whose values are what ``--box`` and
``--box-fit`` accept (re-exported by :mod:`.boxes`)."""

from __future__ import annotations

from enum import StrEnum

__all__ = ["BOX_FITS", "BOX_MODES", "BoxFit", "BoxMode"]


class BoxMode(StrEnum):
    """``--box``: the rectangle of the visible mask (the thesis) or of the whole vehicle."""

    VISIBLE = "visible"
    AMODAL = "amodal"


class BoxFit(StrEnum):
    """``--box-fit``: the minimum-area rectangle of the largest region's pixel centres grown
    by 0.25 px per side (default), or of the 3 x 3-dilated contour (the thesis literally)."""

    PIXELS = "pixels"
    DILATED = "dilated"


#: the values the CLI and configs accept, in order (:class:`BoxMode`, :class:`BoxFit`)
BOX_MODES: tuple[str, ...] = tuple(m.value for m in BoxMode)
BOX_FITS: tuple[str, ...] = tuple(m.value for m in BoxFit)
