"""``aerial-synth assets list`` and ``aerial-synth assets preview``.

Nothing heavy is imported at module import time (the top-level ``--help`` stays instant):
the catalog module is light (numpy, PyYAML when a catalog is read); the contact sheet's
renderer is imported when it runs.
"""

from __future__ import annotations

import argparse

from ..errors import ConfigError
from ..validators import arg_float
from .catalog import load_catalog

__all__ = ["register", "format_table"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "assets",
        help="vehicle catalog: list models, draw a contact sheet of every variant",
        description="Vehicle assets: the catalog's models, colours and meshes.",
    )
    sub = p.add_subparsers(dest="assets_command", metavar="ACTION")
    sub.required = True

    pl = sub.add_parser("list", help="print a table of models, sizes, classes and weights")
    pl.add_argument("--catalog", metavar="FILE", default=None,
                    help="catalog YAML (default: the bundled vehicle_assets/catalog.yaml)")
    pl.set_defaults(func=_cmd_list)

    pp = sub.add_parser("preview", help="write a top-down contact sheet (PNG) of every variant")
    pp.add_argument("--catalog", metavar="FILE", default=None,
                    help="catalog YAML (default: the bundled vehicle_assets/catalog.yaml)")
    pp.add_argument("--out", metavar="PNG", required=True, help="output image (.png)")
    pp.add_argument("--gsd", type=arg_float("--gsd", 0.005, 0.5), default=0.04, metavar="M",
                    help="metres per pixel of the sheet (default 0.04)")
    pp.set_defaults(func=_cmd_preview)


def format_table(catalog) -> str:
    """The catalog as a plain-text table (models, then a colour summary line)."""
    pm = catalog.model_probabilities
    header = (
        "model", "pack", "class", "length_m", "width_m", "height_m", "weight", "share", "source"
    )
    rows = [header]
    for m, p in zip(catalog.models, pm):
        rows.append(
            (m.name, str(m.pack), m.cls, f"{m.length_m:.2f}", f"{m.width_m:.2f}",
             f"{m.height_m:.2f}", f"{m.weight:g}", f"{p:.1%}", m.source)
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    right = {1, 3, 4, 5, 6, 7}
    lines = []
    for k, r in enumerate(rows):
        cells = [
            c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))
        ]
        lines.append("  ".join(cells).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    pc = catalog.color_probabilities
    cols = ", ".join(
        f"{c.name} {p:.0%}" if p >= 0.01 else f"{c.name} {p:.1%}"
        for c, p in zip(catalog.colors, pc)
    )
    lines.append("")
    lines.append(f"colours ({len(catalog.colors)}): {cols}")
    lines.append(f"variants: {len(catalog.models)} models x {len(catalog.colors)} colours = "
                 f"{len(catalog.models) * len(catalog.colors)}")
    return "\n".join(lines)


def _cmd_list(args: argparse.Namespace) -> int:
    print(format_table(load_catalog(args.catalog)))
    return 0


def _cmd_preview(args: argparse.Namespace) -> int:
    if not str(args.out).lower().endswith(".png"):
        raise ConfigError(f"--out: expected a .png file name, got {args.out!r}")
    from .preview import write_contact_sheet  # lazy: ray casting, meshes; not for --help

    n, w, h = write_contact_sheet(args.out, args.catalog, args.gsd)
    print(f"wrote {args.out}: {n} variants, {w}x{h} px at {args.gsd} m/px")
    return 0
