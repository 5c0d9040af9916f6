"""Command-line entry point: ``aerial-synth``.

Thin: parse arguments, call the API, print a short summary. Every subcommand lives in the
``cli`` module of its package and registers itself with :func:`register`; those modules
import nothing heavy at import time so ``aerial-synth --help`` stays instant.
User mistakes (:class:`AerialSynthError`) print one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from . import __version__
from .errors import AerialSynthError

# (module, ...) each exposing register(subparsers) that adds its commands and sets `func`.
_COMMAND_MODULES = (
    "aerial_synth.scene.cli",
    "aerial_synth.vehicles.cli",
    "aerial_synth.placement.cli",
    "aerial_synth.render.cli",
    "aerial_synth.dataset.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="aerial-synth",
        description="Synthetic nadir aerial images of vehicles with exact oriented-box labels.",
    )
    parser.add_argument("--version", action="version", version=f"aerial-synth {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except AerialSynthError as exc:
        print(f"aerial-synth: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("aerial-synth: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
