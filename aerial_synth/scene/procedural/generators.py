"""The registry of procedural scene generators.

A generator is a module with ``GENERATOR = Generator(name, build)``, where ``build(builder,
spec)`` fills a :class:`~aerial_synth.scene.procedural.builder.Builder` from a checked spec.
Adding one is that module plus one line in :data:`BUILTIN` (or :meth:`REGISTRY.register
<aerial_synth.registry.Registry.register>` at run time). A generator without a schema in
``spec.py`` checks its own keys.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ...errors import SceneError
from ...registry import Registry

__all__ = ["Generator", "BUILTIN", "REGISTRY"]


@dataclass(frozen=True)
class Generator:
    """A scene generator: ``build(builder, spec)`` adds roads, buildings, ... to the builder."""

    name: str
    build: Callable


#: generator name -> module holding its ``GENERATOR`` (imported on first use)
BUILTIN = {
    "city_park": "aerial_synth.scene.procedural.city_park",
    "suburb": "aerial_synth.scene.procedural.suburb",
    "highway": "aerial_synth.scene.procedural.highway",
    "city": "aerial_synth.scene.procedural.city",
    "depot": "aerial_synth.scene.procedural.parking",
    "residential": "aerial_synth.scene.procedural.residential",
    "rural": "aerial_synth.scene.procedural.rural",
}

REGISTRY = Registry(BUILTIN, attr="GENERATOR", noun="generator", option="generator", kind="a Generator",
                    is_entry=lambda o: isinstance(o, Generator), error=SceneError)
