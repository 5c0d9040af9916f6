"""Tiles of a real image rescaled to a target GSD, checked before anything is allocated
(``mix`` and ``sim2real``): the rescaled size against OpenCV's image limits, the tile count
against :data:`MAX_TILES_PER_IMAGE`, and the memory the image and its copies need (issue 37:
``gsd:1e300`` in a label made the tile list alone take 14 GB)."""

from __future__ import annotations

from ..errors import EvaluationError
from ..memory import check_memory
from ..safe_input import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE

__all__ = ["MAX_TILES_PER_IMAGE", "tile_count", "tile_origins", "check_scaled_plan"]


#: Most tiles one real image may be cut into: a 16,384 px square in 64 px tiles without
#: overlap is 65,536; a plan beyond this would spend its memory on the list of tiles alone.
MAX_TILES_PER_IMAGE = 1_000_000


def tile_count(size: int, tile: int, overlap: int) -> int:
    """len(tile_origins(size, tile, overlap)), without building the list."""
    if size <= tile:
        return 1
    return -(-(size - tile) // (tile - overlap)) + 1


def tile_origins(size: int, tile: int, overlap: int) -> list[int]:
    """Tile starts along one axis, as the DOTA devkit: every ``tile - overlap`` px; the last
    tile ends at ``size`` (one tile at 0 when ``size <= tile``)."""
    slide = tile - overlap
    n = tile_count(size, tile, overlap)
    if n > MAX_TILES_PER_IMAGE:  # callers check first (check_scaled_plan); a last guard
        raise EvaluationError(f"--tile {tile} --overlap {overlap}: {n:,} tiles along {size:,} px, "
                              f"expected at most {MAX_TILES_PER_IMAGE:,} per image")
    return [left for left in range(0, slide * (n - 1), slide)] + [max(size - tile, 0)]


def check_scaled_plan(where: str, w: int, h: int, f: float, tile: int | None, overlap: int,
                      error: type[Exception] = EvaluationError) -> tuple[int, int]:
    """The size ``(nw, nh)`` of a ``w`` x ``h`` image rescaled by ``f``, refused in one line
    (before anything is allocated) when it exceeds OpenCV's image limits, the memory
    available, or :data:`MAX_TILES_PER_IMAGE` tiles of ``tile`` px."""
    fw, fh = w * f, h * f
    if fw * fh > MAX_IMAGE_PIXELS or max(fw, fh) > MAX_IMAGE_SIDE:
        raise error(f"{where}: rescaled by {f:.4g} to the target GSD, its {w} x {h} px would "
                    f"become {fw:.4g} x {fh:.4g} px, more than OpenCV's limit of "
                    f"{MAX_IMAGE_PIXELS:,} pixels ({MAX_IMAGE_SIDE:,} a side); choose a larger --gsd")
    nw, nh = max(1, int(round(fw))), max(1, int(round(fh)))
    if tile is not None:
        n = tile_count(nw, tile, overlap) * tile_count(nh, tile, overlap)
        if n > MAX_TILES_PER_IMAGE:
            raise error(f"{where}: {nw} x {nh} px in --tile {tile} --overlap {overlap} gives {n:,} "
                        f"tiles, expected at most {MAX_TILES_PER_IMAGE:,} per image; choose a "
                        "larger --tile, a smaller --overlap or a larger --gsd")
    # the decoded image, its rescaled copy and one tile's copy, 3 bytes a pixel
    check_memory(3 * (w * h + 2 * nw * nh), f"{where}: rescaled to {nw} x {nh} px, it",
                 "choose a larger --gsd", error)
    return nw, nh
