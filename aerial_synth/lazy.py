"""The one lazy loader of the package ``__init__`` files: names that load their module on
first use (``aerial-synth --help`` imports the packages, not the heavy modules).

In a package's ``__init__.py``::

    from ..lazy import lazy_module_attrs
    __getattr__, __dir__ = lazy_module_attrs(__name__, {"Name": "submodule", ...}, __all__)
"""

from __future__ import annotations

import importlib
import sys

__all__ = ["lazy_module_attrs"]


def lazy_module_attrs(package: str, table: dict, names=()):
    """``(__getattr__, __dir__)`` for package ``package``: ``table`` maps a public name to the
    submodule (relative to ``package``) that defines it; the value is imported on first use
    and kept in the package's namespace. ``names``: the package's ``__all__``."""
    table = dict(table)

    def __getattr__(name: str):
        mod = table.get(name)
        if mod is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{mod}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(names) | set(table))

    return __getattr__, __dir__
