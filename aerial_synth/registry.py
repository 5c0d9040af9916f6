"""The one registry helper: label formats, export engines, render backends, procedural scene
generators and vehicle bodies are each a
:class:`Registry` of built-ins (name -> module, imported on first use) plus entries
registered at run time (plugins, tests)."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

__all__ = ["Registry"]


class Registry:
    """Named entries: ``builtin`` maps a name to the module whose ``attr`` is the entry, or a
    mapping name -> entry for a module holding several (loaded on first :meth:`get`);
    :meth:`register` adds one at run time.

    noun     : what an entry is, in messages ("format", "engine", "backend")
    option   : the option an unknown name is reported under ("--format", ...)
    kind     : what ``attr`` must be, in messages ("a LabelFormat", "an Engine", ...)
    is_entry : whether an object is an entry of this registry
    error    : the exception class raised (one line)
    """

    def __init__(self, builtin: dict[str, str], *, attr: str, noun: str, option: str, kind: str,
                 is_entry: Callable[[object], bool], error: type[Exception]):
        self.builtin = builtin
        self.attr, self.noun, self.option, self.kind = attr, noun, option, kind
        self.is_entry, self.error = is_entry, error
        self.loaded: dict = {}
        self.extra: dict = {}  # registered at run time

    def names(self) -> tuple[str, ...]:
        """Every name: built-ins first (in their order), then those registered at run time."""
        return tuple(self.builtin) + tuple(n for n in self.extra if n not in self.builtin)

    def get(self, name: str):
        """The entry called ``name``; an unknown name raises :attr:`error` listing the valid ones."""
        if name in self.extra:
            return self.extra[name]
        if name in self.loaded:
            return self.loaded[name]
        if name not in self.builtin:
            raise self.error(f"{self.option}: unknown {self.noun} {name!r}; expected one of "
                             f"{', '.join(self.names())}")
        obj = getattr(importlib.import_module(self.builtin[name]), self.attr, None)
        if isinstance(obj, Mapping):  # a module holding several entries: {name: entry}
            obj = obj.get(name)
        if not self.is_entry(obj) or obj.name != name:
            raise self.error(f"{self.noun} module {self.builtin[name]}: expected {self.attr} = {self.kind} "
                             f"named {name!r}, got {obj!r}")
        self.loaded[name] = obj
        return obj

    def register(self, obj, *, replace: bool = False):
        """Add an entry at run time (a new name unless ``replace``)."""
        if not self.is_entry(obj) or not getattr(obj, "name", None):
            raise self.error(f"register: expected {self.kind} with a name, got {obj!r}")
        if obj.name in self.names() and not replace:
            raise self.error(f"register: {self.noun} {obj.name!r} is already registered")
        self.extra[obj.name] = obj
        return obj

    def unregister(self, name: str) -> None:
        """Remove an entry registered at run time (built-ins stay)."""
        self.extra.pop(name, None)
