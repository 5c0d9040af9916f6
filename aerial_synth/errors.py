"""One small exception tree.

Every user mistake raises an :class:`AerialSynthError` subclass whose message names the
file or field, what was expected and what arrived. The CLI prints that one line and exits
with status 2; no traceback is shown for these.
"""

from __future__ import annotations

__all__ = [
    "own_warnings",
    "AerialSynthError",
    "ConfigError",
    "SceneError",
    "AssetError",
    "PlacementError",
    "CameraError",
    "RenderError",
    "ExportError",
    "OutputError",
    "EvaluationError",
    "LabelFormatError",
]


class AerialSynthError(Exception):
    """Base class of every error caused by bad input or configuration."""


class ConfigError(AerialSynthError, ValueError):
    """A configuration value (YAML field, CLI option) is invalid."""


class SceneError(AerialSynthError):
    """A scene file, label-rules file or scene spec cannot be used."""


class AssetError(AerialSynthError):
    """A vehicle catalog entry or vehicle mesh cannot be used."""


class PlacementError(AerialSynthError):
    """Placement cannot run (no road found, bad scenario parameters, ...)."""


class CameraError(AerialSynthError):
    """An invalid camera setting (altitude, image size, GSD/FOV/focal, tilt)."""


class RenderError(AerialSynthError):
    """Rendering cannot run (e.g. an optional backend is unavailable)."""


class ExportError(AerialSynthError):
    """A dataset export cannot run (unknown format, bad output folder, ...)."""


class EntryPointError(ExportError):
    """A worker process, importing the main module of a script without an ``if __name__ ==
    '__main__'`` guard, was about to export again (see
    :func:`aerial_synth.dataset.engines.fork_server.check_entry_point`)."""


class OutputError(AerialSynthError):
    """An output path cannot be written (not a regular file, parent is a file, read-only, ...)."""


class EvaluationError(AerialSynthError):
    """Evaluation, mixing or statistics input cannot be used (bad label or prediction file, ...)."""


class LabelFormatError(ExportError, EvaluationError):
    """A label file does not follow its format (names the file and line, what was expected and
    what arrived). Raised by :mod:`aerial_synth.formats` for the exporter's own files and for
    real-world files read by ``eval``, ``mix``, ``stats`` and ``show``, so it is both an
    :class:`ExportError` and an :class:`EvaluationError`."""


def own_warnings(caught) -> list[str]:
    """The messages of the recorded warnings ``caught`` that aerial-synth raised (its warning
    classes live in its own modules). A library's one-time import warning (open3d 0.18's
    "built with CUDA support, but no suitable CUDA devices") reaches only the first placement
    of a process: recorded in metadata, it made an image's meta depend on which worker made it."""
    return [str(w.message) for w in caught if w.category.__module__.startswith("aerial_synth.")]
