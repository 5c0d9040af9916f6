"""Label rules: which label, material and colour each node/mesh name of a scene file gets.

Label rules (YAML, see docs/scenes.md) map node/mesh names to labels with case-insensitive
globs or ``re:`` regular expressions; the first matching rule wins. A name that starts with
``<label>__`` (what :func:`~aerial_synth.scene.io.export_glb` writes) takes that label
before any rule. Names no rule matches get the label ``unknown``; they are counted in
``scene.meta["unmatched"]`` and, unless the rules file gives its own ``label_config``,
``unknown`` is added to the obstacle set so placement keeps away from unlabelled geometry.
"""

from __future__ import annotations

import fnmatch
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from .. import validators as V
from ..errors import AerialSynthError, SceneError
from ..safe_input import load_yaml_file, shown, user_regex
from .georef import check_crs
from .model import LABEL_IDS, LABELS, MATERIAL_IDS, MATERIALS, LabelConfig

__all__ = ["DEFAULT_RULES", "LabelRule", "LabelRules", "load_rules", "read_yaml"]

#: Built-in rules, tried in order after any user rules (case-insensitive globs).
DEFAULT_RULES: tuple[tuple[str, str], ...] = (
    ("lane_marking*", "lane_marking"),
    ("marking*", "lane_marking"),
    ("lane*", "lane_marking"),
    ("crosswalk*", "lane_marking"),
    ("road*", "road"),
    ("street*", "road"),
    ("asphalt*", "road"),
    ("highway*", "road"),
    ("sidewalk*", "sidewalk"),
    ("pavement*", "sidewalk"),
    ("footpath*", "sidewalk"),
    ("kerb*", "sidewalk"),
    ("curb*", "sidewalk"),
    ("parking*", "parking"),
    ("driveway*", "parking"),
    ("building*", "building"),
    ("house*", "building"),
    ("roof*", "building"),
    ("wall*", "building"),
    ("trunk*", "trunk"),
    ("tree*", "tree"),
    ("crown*", "tree"),
    ("foliage*", "tree"),
    ("leaves*", "tree"),
    ("bush*", "tree"),
    ("grass*", "ground"),
    ("ground*", "ground"),
    ("terrain*", "ground"),
    ("lawn*", "ground"),
    ("soil*", "ground"),
    ("water*", "water"),
    ("lake*", "water"),
    ("pond*", "water"),
    ("river*", "water"),
    ("pole*", "pole"),
    ("lamp*", "pole"),
    ("post*", "pole"),
    ("sign*", "pole"),
    ("vehicle*", "vehicle"),
    ("car*", "vehicle"),
)

_UNITS = {"m": 1.0, "metre": 1.0, "meter": 1.0, "cm": 0.01, "mm": 0.001, "km": 1000.0,
          "ft": 0.3048, "in": 0.0254}
_RULE_KEYS = {"match", "label", "material", "color"}
_TOP_KEYS = {"units", "up_axis", "rules", "include_defaults", "label_config", "default_label",
             "crs"}


@dataclass(frozen=True)
class LabelRule:
    """One rule: a glob (case-insensitive) or ``re:`` pattern -> label (+ material/colour)."""

    match: str
    label: str
    material: str | None = None
    color: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.label not in LABEL_IDS:
            raise SceneError(
                f"label rule {self.match!r}: unknown label {self.label!r}; expected one of "
                f"{', '.join(LABELS)}"
            )
        if self.material is not None and self.material not in MATERIAL_IDS:
            raise SceneError(
                f"label rule {self.match!r}: unknown material {self.material!r}; expected one "
                f"of {', '.join(sorted(MATERIAL_IDS))}"
            )
        if self.match.startswith("re:"):
            pat = user_regex(self.match[3:], f"label rule {self.match!r}", SceneError,
                             ignore_case=True)
        else:  # a glob: fnmatch's own translation, which cannot backtrack
            pat = re.compile(fnmatch.translate(self.match), re.IGNORECASE)  # guard: a glob
        object.__setattr__(self, "_pattern", pat)

    def matches(self, name: str) -> bool:
        pat = self._pattern  # type: ignore[attr-defined]
        if self.match.startswith("re:"):
            return pat.search(name) is not None
        return pat.match(name) is not None


@dataclass(frozen=True)
class LabelRules:
    """A parsed label-rules file.

    rules : user rules first, then (unless include_defaults is false) the built-in ones
    units_m : metres per file unit (None = the file's own convention: 1.0)
    up_axis : "y" or "z" (None = y for glTF/GLB, z for OBJ/PLY)
    label_config : probing sets, or None for the default (+ ``unknown`` as obstacle)
    default_label : label for names no rule matches
    crs : the CRS of the file's coordinates (e.g. ``EPSG:32632``), or None
    """

    rules: tuple[LabelRule, ...]
    units_m: float | None = None
    up_axis: str | None = None
    label_config: LabelConfig | None = None
    default_label: str = "unknown"
    crs: str | None = None
    source: str = "built-in rules"

    def label_for(self, name: str) -> LabelRule | None:
        """The first rule matching ``name`` (a ``<label>__`` prefix wins), or None."""
        head, sep, _ = name.partition("__")
        if sep and head.lower() in LABEL_IDS:
            return LabelRule(match=f"{head}__*", label=head.lower())
        for r in self.rules:
            if r.matches(name):
                return r
        return None


def _default_rule_objects() -> tuple[LabelRule, ...]:
    return tuple(LabelRule(m, lab) for m, lab in DEFAULT_RULES)


def read_yaml(path: Path, what: str, root: str | Path | None = None) -> Any:
    """The YAML file ``path``; SceneError naming ``what`` and the file when it is missing,
    unreadable or broken, or nests or expands aliases beyond :mod:`..safe_input`'s budgets.
    ``root``: the folder the file was found in without the user naming it (it must not lead
    out of it)."""
    return load_yaml_file(path, f"{what} {shown(path)}", SceneError, root=root)


def load_rules(path: str | Path | None, root: str | Path | None = None) -> LabelRules:
    """Parse a label-rules YAML file; None gives the built-in rules. ``root``: the folder a
    file found automatically (a mesh's ``NAME.labels.yaml``) must stay in."""
    if path is None:
        return LabelRules(rules=_default_rule_objects())
    path = Path(path)
    data = read_yaml(path, "label rules", root)
    try:
        return _rules_from_mapping(data, str(path))
    except AerialSynthError as exc:
        msg = str(exc)
        if str(path) not in msg:
            msg = f"label rules {path}: {msg}"
        raise SceneError(msg) from None


def _rules_from_mapping(data: Any, where: str) -> LabelRules:
    """Validate every field of a parsed label-rules file (messages name the field)."""
    E = SceneError
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise SceneError(
            f"expected a mapping with keys such as 'rules', got {V.show(data)}"
        )
    V.known_keys("top level", data, sorted(_TOP_KEYS), error=E)
    raw = data.get("rules")
    items: list[tuple[str, Any]] = []
    if raw is None:
        pass
    elif isinstance(raw, Mapping):  # compact form {pattern: label}
        for k, v in raw.items():
            items.append((f"rules[{k!r}]", {"match": k, "label": v}))
    elif isinstance(raw, list):
        items = [(f"rules[{i}]", it) for i, it in enumerate(raw)]
    else:
        raise SceneError(f"rules: expected a list of rules or a mapping pattern: label, got {V.show(raw)}")
    rules = []
    for field, it in items:
        if not isinstance(it, Mapping):
            raise SceneError(f"{field}: expected a mapping with 'match' and 'label', got {V.show(it)}")
        V.known_keys(field, it, sorted(_RULE_KEYS), error=E)
        for key in ("match", "label"):
            if key not in it:
                raise SceneError(f"{field}: missing key {key!r}; expected 'match' and 'label'")
        match = it["match"]
        if not isinstance(match, str) or not match:
            raise SceneError(f"{field}.match: expected a glob or 're:' pattern (text), got {V.show(match)}")
        label = it["label"]
        if not isinstance(label, str) or label not in LABEL_IDS:
            raise SceneError(f"{field}.label: expected one of {', '.join(LABELS)}, got {V.show(label)}")
        material = it.get("material")
        if material is not None and (not isinstance(material, str) or material not in MATERIAL_IDS):
            raise SceneError(
                f"{field}.material: expected one of {', '.join(MATERIALS)}, got {V.show(material)}"
            )
        col = it.get("color")
        if col is not None:
            col = V.sequence_of_numbers(f"{field}.color", col, 3, error=E)
            if not all(0.0 <= c <= 1.0 for c in col):
                raise SceneError(f"{field}.color: expected [r, g, b] in 0..1, got {V.show(it['color'])}")
        rules.append(LabelRule(match, label, material, col))
    if V.boolean("include_defaults", data.get("include_defaults", True), error=E):
        rules.extend(_default_rule_objects())
    units = data.get("units")
    units_m = None
    if units is not None:
        if isinstance(units, str) and units.strip().lower() in _UNITS:
            units_m = _UNITS[units.strip().lower()]
        else:
            try:
                units_m = V.in_range("units", units, 0.0, 1e6, lo_open=True, error=E)
            except SceneError:
                raise SceneError(
                    f"units: expected a number of metres per file unit (> 0) or one of "
                    f"{', '.join(sorted(_UNITS))}, got {V.show(units)}"
                ) from None
    up = data.get("up_axis")
    if up is not None:
        if not isinstance(up, str) or up.strip().lower() not in ("y", "z"):
            raise SceneError(f"up_axis: expected y or z, got {V.show(up)}")
        up = up.strip().lower()
    lc = data.get("label_config")
    label_config = None
    if lc is not None:
        V.mapping("label_config", lc, error=E)
        label_config = LabelConfig.from_mapping(lc) if lc else None
    default_label = data.get("default_label", "unknown")
    if not isinstance(default_label, str) or default_label not in LABEL_IDS:
        raise SceneError(f"default_label: expected one of {', '.join(LABELS)}, got {V.show(default_label)}")
    crs = data.get("crs")
    if crs is not None:
        crs = check_crs(crs, "crs")
    return LabelRules(
        rules=tuple(rules),
        units_m=units_m,
        up_axis=up,
        label_config=label_config,
        default_label=default_label,
        crs=crs,
        source=where,
    )


# --------------------------------------------------------------------------- meshes
