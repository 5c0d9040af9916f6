"""The registry of procedural vehicle bodies.

A body is ``Body(name, build)`` where ``build(length_m, width_m, height_m)`` returns the
vehicle's :class:`~aerial_synth.vehicles.parts.Part` list in the vehicle frame (+x forward,
origin at the footprint centre on the ground). Adding one is a module holding ``BODIES =
Body(...)`` (or a mapping name -> Body) plus one line in :data:`BUILTIN` (or :meth:`REGISTRY.register
<aerial_synth.registry.Registry.register>` at run time); a catalog entry may then name it
as its ``body``. The built-in bodies live in vehicles/meshes.py (``BODIES``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..errors import AssetError
from ..registry import Registry
from .model import BODY_TYPES

__all__ = ["Body", "BUILTIN", "REGISTRY"]


@dataclass(frozen=True)
class Body:
    """A procedural body type: ``build(L, W, H)`` -> parts."""

    name: str
    build: Callable


#: body name -> module holding it (``BODIES``: a Body, or {name: Body} for several)
BUILTIN = {name: "aerial_synth.vehicles.meshes" for name in BODY_TYPES}

REGISTRY = Registry(BUILTIN, attr="BODIES", noun="body", option="body", kind="a Body",
                    is_entry=lambda o: isinstance(o, Body), error=AssetError)
