"""Export parameters (:class:`ExportConfig`) and the export's result (:class:`ExportResult`).

Every field of :class:`ExportConfig` changes the exported bytes, so all go into the manifest;
run options that do not (workers, resume, force, progress) are arguments of
:func:`~aerial_synth.dataset.export.export_dataset` instead.

The camera, the boxes and the render options are the dataclasses that own their defaults and
checks (``camera``: :class:`~aerial_synth.camera.CameraConfig`, ``box``:
:class:`~aerial_synth.annotate.boxes.BoxConfig`, ``render``:
:class:`~aerial_synth.render.config.RenderOptions`), nested. The manifest keeps its flat
parameter names (:data:`CAMERA_KEYS`, :data:`RENDER_KEYS`; :meth:`ExportConfig.to_dict`),
so its bytes are those of every earlier version and older exports can be resumed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from pathlib import Path

from .. import validators as v
from ..annotate.boxes import BoxConfig
from ..camera import MAX_ALTITUDE_M, MAX_GSD_M, MIN_ALTITUDE_M, MIN_GSD_M, CameraConfig
from ..errors import CameraError, ConfigError, ExportError
from ..formats.registry import parse_names
from ..render.config import RenderOptions
from .gsd import GsdRange, parse_range, widest_camera_config
from .scene_mix import parse_mix
from .seeds import PLACEMENT_STREAM

__all__ = ["CAMERA_KEYS", "IMAGE_EXTS", "PLACEMENT_STREAM", "RENDER_KEYS", "SPLITS", "ExportConfig",
           "ExportResult"]

SPLITS = ("train", "val")
IMAGE_EXTS = ("png", "jpg")
#: most images one export may hold (the plan and the manifest grow with it; about 9 days of
#: rendering on 2 cores at 0.8 s an image): a larger dataset is several exports
MAX_IMAGES = 1_000_000
#: parameters that appear in the manifest only when set (added after manifest version 1)
_OPTIONAL_FIELDS = ("bbox", "crs", "distractors", "tile_m", "margin_m", "gsd_range",
                    "altitude_range", "scene_mix")
#: the manifest's names of ``camera``'s fields, in the manifest's order (an export sets no
#: focal_px / fov_deg: its lens comes from gsd_m or a range)
CAMERA_KEYS = ("width_px", "height_px", "altitude_m", "gsd_m", "max_tilt_deg")
#: manifest name -> ``render``'s field; each appears only when not RenderOptions' default
#: (added after manifest version 1)
RENDER_KEYS = {"render_preset": "preset", "randomise": "randomise", "backend": "backend"}


@dataclass(frozen=True)
class ExportConfig:
    """Every parameter that affects the exported bytes (all go into the manifest).

    scene / labels / scene_seed : as ``load_scene`` takes them
    bbox / crs          : OSM extracts only, as ``load_scene`` takes them (text)
    scenario            : traffic scenario name or YAML path
    images              : number of images (>= 1)
    formats             : registered format names (``formats.registry``), any order; stored
                          in registry order
    split               : fraction of images in train, in (0, 1]; the first
                          round(split * images) indices (at least one) are train
    seed                : dataset seed (0 is a seed like any other)
    images_per_placement: a fresh placement every K images (K >= 1)
    n_vehicles / n_lines: how much to place per placement (default: the scenario's)
    camera              : the camera (CameraConfig: width_px, height_px, altitude_m, gsd_m,
                          max_tilt_deg; not focal_px / fov_deg); with a range, its altitude_m
                          or gsd_m fixes the lens (aerial_synth.dataset.gsd)
    box                 : box extraction and flag thresholds (BoxConfig)
    image_ext           : "png" (lossless) or "jpg" (quality 95)
    simple_vehicles     : box meshes instead of catalog meshes (fast tests)
    render              : shading preset ("full" or "fast") and randomise mode ("none" or
                          "textures", domain randomisation): RenderOptions
    distractors         : distractors per hectare (manholes, containers, signs, ...; never
                          labelled), drawn once per dataset from SeedSequence([seed,
                          DISTRACTOR_KEY]); None or 0 = none
    gsd_range / altitude_range : (lo, hi) metres: each image draws its nadir GSD from the
                          range (log-uniform), the lens fixed (aerial_synth.dataset.gsd);
                          at most one, and gsd_range not with camera.gsd_m
    scene_mix           : placement groups draw (scene, scenario) from weighted entries
                          (aerial_synth.dataset.scene_mix); stored as its canonical text;
                          scene and scenario then only fill entries that name no scenario
    tile_m / margin_m   : render a tiled world (aerial_synth.dataset.tiled): square tiles of
                          tile_m metres, each worker holding only the tiles a placement group
                          needs; margin_m is the placement margin (None = 60 m, resolved here)
    """

    scene: str = "city_park"
    labels: str | None = None
    scene_seed: int | None = None
    bbox: str | None = None
    crs: str | None = None
    scenario: str = "jam"
    images: int = 10
    formats: tuple[str, ...] = ("dota",)
    split: float = 0.8
    seed: int = 0
    images_per_placement: int = 10
    n_vehicles: int | None = None
    n_lines: int | None = None
    camera: CameraConfig = field(default_factory=CameraConfig)
    box: BoxConfig = field(default_factory=BoxConfig)
    image_ext: str = "png"
    simple_vehicles: bool = False
    render: RenderOptions = field(default_factory=RenderOptions)
    distractors: float | None = None
    tile_m: float | None = None
    margin_m: float | None = None
    gsd_range: tuple[float, float] | None = None
    altitude_range: tuple[float, float] | None = None
    scene_mix: str | None = None

    def __post_init__(self):
        E = ExportError
        s = object.__setattr__
        for name in ("scene", "labels", "scenario"):  # paths are stored as text (manifest)
            val = getattr(self, name)
            if isinstance(val, os.PathLike):
                s(self, name, os.fspath(val))
        s(self, "formats", parse_names(self.formats))
        s(self, "images", v.integer("--images", self.images, 1, MAX_IMAGES, error=E))
        s(self, "split", v.in_range("--split", self.split, 0.0, 1.0, lo_open=True, error=E))
        s(self, "seed", v.integer("--seed", self.seed, 0, error=E))
        s(self, "images_per_placement",
          v.integer("--images-per-placement", self.images_per_placement, 1, error=E))
        if self.scene_seed is not None:
            s(self, "scene_seed", v.integer("--scene-seed", self.scene_seed, 0, error=E))
        if self.n_vehicles is not None:
            s(self, "n_vehicles", v.integer("--vehicles", self.n_vehicles, 1, error=E))
        if self.n_lines is not None:
            s(self, "n_lines", v.integer("--lines", self.n_lines, 1, error=E))
        v.one_of("--image-ext", self.image_ext, IMAGE_EXTS, error=E)
        if not isinstance(self.scene, str) or not self.scene:
            raise E(f"--scene: expected a scene name or file, got {v.show(self.scene)}")
        if self.labels is not None and (not isinstance(self.labels, str) or not self.labels):
            raise E(f"--labels: expected a label-rules file, got {v.show(self.labels)}")
        if not isinstance(self.scenario, str) or not self.scenario:
            raise E(f"--scenario: expected a scenario name or file, got {v.show(self.scenario)}")
        for name, cls in (("camera", CameraConfig), ("box", BoxConfig), ("render", RenderOptions)):
            if not isinstance(getattr(self, name), cls):  # each checks its own fields
                raise ConfigError(f"{name}: expected a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        if self.camera.focal_px is not None or self.camera.fov_deg is not None:
            raise E("camera: an export's lens is set by gsd_m (or a --gsd / --altitude range), "
                    f"got focal_px {v.show(self.camera.focal_px)}, fov_deg {v.show(self.camera.fov_deg)}")
        if self.distractors is not None:
            s(self, "distractors", v.in_range("--distractors", self.distractors, 0.0, 1000.0,
                                              error=E))
        if self.tile_m is not None:
            # lazy: tiled imports placement and the scene's tiles (shapely); configs are read at --help
            from .tiled import check_tiled_config

            s(self, "tile_m", float(v.in_range("--tile-m", self.tile_m, 0.0, 1e9, lo_open=True, error=E)))
            s(self, "margin_m", check_tiled_config(self))
        elif self.margin_m is not None:
            raise E(f"--margin-m: only with --tile-m (a tiled export), got --margin-m {v.show(self.margin_m)}")
        self._check_ranges_and_mix()
        self._check_range_cameras()  # both ends of a range within the camera's bounds

    def _check_range_cameras(self) -> None:
        """The cameras at both ends of a GSD or altitude range (lens fixed, altitude = GSD x
        focal) must lie within :mod:`aerial_synth.camera`'s bounds: ``--gsd 0.005:1`` at
        60 m implies an altitude of 4 m at its low end."""
        r = GsdRange.of(self)
        if r is None:
            return
        opt = "--gsd" if self.gsd_range is not None else "--altitude"
        for g in (r.gsd_lo_m, r.gsd_hi_m):
            try:
                r.camera_config(self, g)
            except CameraError as exc:
                raise ExportError(f"{opt}: the range's lens (focal {r.focal_px:.4g} px) at "
                                  f"{g:.3g} m/px: {exc}") from None

    def _check_ranges_and_mix(self) -> None:
        E = ExportError
        s = object.__setattr__
        for name, opt, lo, hi in (("gsd_range", "--gsd", MIN_GSD_M, MAX_GSD_M),
                                  ("altitude_range", "--altitude", MIN_ALTITUDE_M, MAX_ALTITUDE_M)):
            val = getattr(self, name)
            if val is not None:  # the camera's bounds (aerial_synth.camera) hold for ranges too
                r = parse_range(opt, val, error=E, hi=hi, lo=lo)
                if not isinstance(r, tuple):
                    raise E(f"{opt}: expected a range LO:HI for {name}, got {v.show(val)}")
                s(self, name, r)
        if self.gsd_range is not None and self.altitude_range is not None:
            raise E(f"--gsd and --altitude: give a range to one of them (both fix the lens), got "
                    f"--gsd {self.gsd_range[0]:g}:{self.gsd_range[1]:g} --altitude "
                    f"{self.altitude_range[0]:g}:{self.altitude_range[1]:g}")
        if self.gsd_range is not None and self.camera.gsd_m is not None:
            raise E(f"--gsd: one value or one range, got gsd_m {v.show(self.camera.gsd_m)} and gsd_range "
                    f"{v.show(self.gsd_range)}")
        if self.scene_mix is not None:
            s(self, "scene_mix", parse_mix(self.scene_mix).text())
            if self.tile_m is not None:
                raise E("--scene-mix: not with --tile-m (a tiled export renders one world)")

    # --------------------------------------------------------------- derived
    @property
    def n_train(self) -> int:
        return max(1, min(self.images, int(round(self.split * self.images))))

    @property
    def splits(self) -> dict[str, int]:
        """Split name -> number of images."""
        return {"train": self.n_train, "val": self.images - self.n_train}

    def camera_config(self) -> CameraConfig:
        """The camera every image fits in: :attr:`camera`, or with a GSD or altitude range
        the one that sees farthest (per image:
        :func:`aerial_synth.dataset.gsd.image_camera_config`)."""
        widest = widest_camera_config(self)
        return self.camera if widest is None else widest

    def to_dict(self) -> dict:
        """Every parameter, as the manifest stores it: flat, under the names and in the order
        of every earlier version (``camera``'s fields as :data:`CAMERA_KEYS`, ``render``'s as
        :data:`RENDER_KEYS`). Fields added after the first release (:data:`_OPTIONAL_FIELDS`,
        :data:`RENDER_KEYS`) are left out while unset or at their default, so a dataset
        exported without them keeps the same manifest bytes and can still be resumed."""
        d = {}
        for f in fields(self):
            val = getattr(self, f.name)
            if f.name in _OPTIONAL_FIELDS and val is None:
                continue
            if f.name == "camera":
                d.update((k, getattr(val, k)) for k in CAMERA_KEYS)
                continue
            if f.name == "render":
                default = RenderOptions()
                d.update((k, getattr(val, a)) for k, a in RENDER_KEYS.items()
                         if getattr(val, a) != getattr(default, a))
                continue
            if f.name == "box":
                val = val.to_dict()
            elif f.name in ("formats", "gsd_range", "altitude_range"):
                val = list(val)
            d[f.name] = val
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "ExportConfig":
        """The inverse of :meth:`to_dict` (a manifest's ``parameters``, any version)."""
        kw = dict(d)
        kw["camera"] = CameraConfig(**{k: kw.pop(k) for k in CAMERA_KEYS if k in kw})
        kw["render"] = RenderOptions(**{a: kw.pop(k) for k, a in RENDER_KEYS.items()
                                        if kw.get(k) is not None})
        for k in RENDER_KEYS:
            kw.pop(k, None)
        kw["box"] = BoxConfig(**kw.get("box", {}))
        kw["formats"] = tuple(kw.get("formats", ()))
        return cls(**kw)


@dataclass(frozen=True)
class ExportResult:
    out_dir: Path
    summary: dict
    elapsed_s: float
    rendered: int
    skipped: int

    def text(self) -> str:
        s = self.summary
        cls = ", ".join(f"{k} {n}" for k, n in s["vehicles_per_class"].items())
        drop = ", ".join(f"{k} {n}" for k, n in s["dropped_reasons"].items()) or "none"
        return (
            f"exported {s['images']} images (train {s['splits']['train']}, val {s['splits']['val']}) "
            f"to {self.out_dir} in {self.elapsed_s:.1f} s ({self.rendered} rendered, "
            f"{self.skipped} resumed): vehicles {cls}; difficult {s['difficult']}; "
            f"dropped {s['dropped']} ({drop})"
        )
