"""Masks -> oriented boxes (heading-aware corner order) and visibility flags."""

from .boxes import (
    BOX_MODES,
    BoxConfig,
    OrientedBox,
    VehicleAnnotation,
    annotate_frame,
    annotate_instances,
    heading_deg_from_vector,
    mask_to_rect_corners,
    order_corners,
    oriented_box,
    shoelace_area,
)

__all__ = [
    "BOX_MODES",
    "BoxConfig",
    "OrientedBox",
    "VehicleAnnotation",
    "annotate_frame",
    "annotate_instances",
    "heading_deg_from_vector",
    "mask_to_rect_corners",
    "order_corners",
    "oriented_box",
    "shoelace_area",
]
