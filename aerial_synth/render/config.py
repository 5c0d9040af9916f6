"""Render options: :class:`RenderConfig` (ranges of the influence factors and switches),
its named presets, and :func:`sample_factors`, which draws one frame's factors.

The choices the CLI offers are enums here, defined once: :class:`Preset` (``--preset``),
:class:`Randomise` (``--randomise``) and :class:`Backend` (``--backend``, the built-in
render backends of :mod:`.backends`). :class:`RenderOptions` is what a command picks by
name (a preset and a randomise mode, with their defaults): ``render``'s options and
``ExportConfig.render``. Reading a config imports no renderer.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, fields
from enum import StrEnum

import numpy as np

from ..errors import ConfigError, RenderError
from ..scene.model import MATERIALS
from ..validators import boolean, in_range, integer, known_keys, one_of, probability
from . import backends

__all__ = ["Backend", "Preset", "Randomise", "RenderConfig", "RenderOptions", "PRESETS",
           "RENDER_PRESETS", "RANDOMISE", "SHADOW_EDGES", "device_spec", "sample_factors"]


class Preset(StrEnum):
    """Shading presets (``--preset``): every realism factor, or the fast subset."""

    FULL = "full"
    FAST = "fast"


class Randomise(StrEnum):
    """``randomise`` modes: "none" (realistic), "textures" (domain randomisation after Tobin et
    al. 2017: every material's colour, the light's colour and the sky's drawn at random)."""

    NONE = "none"
    TEXTURES = "textures"


#: The built-in render backends (``--backend``), named as the registry names them.
Backend = StrEnum("Backend", {name.upper(): name for name in backends.BUILTIN})


_DEVICE = re.compile(r"cpu|cuda(:[0-9]{1,3})?")


def device_spec(value, field: str = "--device") -> str:
    """``value`` if it names a device the way ``--device`` does (``cpu``, ``cuda`` or
    ``cuda:N``); else ConfigError (one line). Whether the device exists is the backend's
    question (:meth:`~.backends.RenderBackend.check`)."""
    s = str(value)
    if not _DEVICE.fullmatch(s):
        raise ConfigError(f"{field}: expected cpu, cuda or cuda:N (N a device index), got {s!r}")
    return s


def _pair(name: str, value, lo: float, hi: float) -> tuple[float, float]:
    """A (low, high) range within [lo, hi], low <= high."""
    field = f"render config {name}"
    expected = f"(low, high) with {lo:g} <= low <= high <= {hi:g}"
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise ConfigError(f"{field}: expected {expected}, got {value!r}")
    a = in_range(f"{field} low", value[0], lo, hi)
    b = in_range(f"{field} high", value[1], lo, hi)
    if a > b:
        raise ConfigError(f"{field}: expected {expected}, got ({a:g}, {b:g})")
    return (a, b)


#: Named presets (keyword overrides of the defaults): ``full`` is every realism factor on
#: (the default); ``fast`` drops ambient occlusion, the sun-disk sampling, procedural
#: texture and material detail (so also the light through crown gaps) and the mirror rays
#: of wet roads, and casts one shadow ray per 4 x 4 block, object-edge pixels taking a
#: neighbouring block sample on their own surface (``shadow_edges="nearest"``; see
#: docs/rendering.md, "Speed", for the measured costs: fast stays within 1.5 x the bare
#: primary cast).
PRESETS: dict[str, dict] = {
    Preset.FULL.value: {},
    Preset.FAST.value: {"ambient_occlusion": False, "soft_shadows": False, "shadow_step": 4,
             "shadow_edges": "nearest", "texture": False, "wet_reflections": False},
}

_PAIRS = {  # name: (lowest, highest) allowed
    "sun_azimuth_deg": (0, 360), "sun_elevation_deg": (1, 90), "sun_radius_deg": (0, 5),
    "haze": (0, 1), "haze_tint": (-1, 1), "overcast": (0, 1), "wet": (0, 1),
    "key_gray": (5, 250), "contrast_cv": (0.01, 2), "contrast_sd_max": (1, 127),
    "exposure": (0.05, 20), "tone_shoulder": (0, 4), "white_balance": (-1, 1),
    "tint": (-0.5, 0.5), "saturation": (0, 3), "blur_sigma_px": (0, 10),
    "chromatic_blur": (0, 2), "noise_sigma": (0, 0.5), "shot_noise": (0, 0.5),
    "jpeg_quality": (1, 100), "vignetting": (0, 0.9), "asphalt_albedo": (0.05, 4),
    "concrete_albedo": (0.05, 4), "ground_albedo": (0.05, 4), "sky_light": (0.1, 5),
    "vegetation_dryness": (0, 1), "road_wear": (0, 1),
}
#: ``shadow_edges`` modes (``shadow_step`` > 1): "cast": a pixel that differs from its
#: block's sample (label, depth) casts its own shadow ray; "nearest": it copies the first
#: sample at its cell's corners on its own surface and casts only when there is none
SHADOW_EDGES = ("cast", "nearest")
#: ``randomise`` modes, as the CLI accepts them (:class:`Randomise`)
RANDOMISE = tuple(m.value for m in Randomise)
#: render presets, as the CLI accepts them (:class:`Preset`)
RENDER_PRESETS = tuple(p.value for p in Preset)


@dataclass(frozen=True)
class RenderConfig:
    """Ranges of the influence factors (each drawn uniformly per frame) and switches.

    A fixed value is a range with low == high, e.g. ``sun_elevation_deg=(40, 40)``.
    overcast / wet / jpeg / grayscale apply with their probability, then their strength is
    drawn. The spreads of the camera factors (key_gray, contrast, white balance, saturation,
    JPEG quality) are chosen to match real aerial imagery: see docs/rendering.md.

    exposure_mode "auto": the camera meters the frame's linear radiance and picks the
    exposure gain that gives the drawn mean gray ``key_gray`` and the tone-curve power that
    gives the drawn gray standard deviation min(contrast_cv x key_gray, contrast_sd_max);
    "fixed": gain ``exposure`` and the display power 1 / 2.2 (a plain camera).
    """

    sun_azimuth_deg: tuple[float, float] = (0.0, 360.0)
    sun_elevation_deg: tuple[float, float] = (25.0, 70.0)
    sun_radius_deg: tuple[float, float] = (0.27, 1.0)
    haze: tuple[float, float] = (0.0, 0.2)
    haze_tint: tuple[float, float] = (-1.0, 1.0)
    overcast_probability: float = 0.25
    overcast: tuple[float, float] = (0.3, 1.0)
    wet_probability: float = 0.15
    wet: tuple[float, float] = (0.4, 1.0)
    exposure_mode: str = "auto"
    key_gray: tuple[float, float] = (48.0, 185.0)
    contrast_cv: tuple[float, float] = (0.25, 0.55)
    contrast_sd_max: tuple[float, float] = (32.0, 50.0)
    exposure: tuple[float, float] = (0.9, 1.1)
    tone_shoulder: tuple[float, float] = (0.0, 0.6)
    white_balance: tuple[float, float] = (-0.2, 0.1)
    tint: tuple[float, float] = (-0.04, 0.04)
    saturation: tuple[float, float] = (0.3, 0.75)
    grayscale_probability: float = 0.1
    blur_sigma_px: tuple[float, float] = (0.4, 0.9)
    chromatic_blur: tuple[float, float] = (0.0, 0.35)
    noise_sigma: tuple[float, float] = (0.002, 0.008)
    shot_noise: tuple[float, float] = (0.01, 0.03)
    jpeg_probability: float = 0.6
    jpeg_quality: tuple[float, float] = (55.0, 95.0)
    vignetting: tuple[float, float] = (0.0, 0.25)
    asphalt_albedo: tuple[float, float] = (0.3, 0.8)
    concrete_albedo: tuple[float, float] = (0.8, 1.15)
    ground_albedo: tuple[float, float] = (0.45, 0.85)
    vegetation_dryness: tuple[float, float] = (0.0, 0.8)
    road_wear: tuple[float, float] = (0.2, 1.0)
    sky_light: tuple[float, float] = (1.3, 2.2)
    randomise: str = "none"
    shadows: bool = True
    soft_shadows: bool = True
    wet_reflections: bool = True
    shadow_step: int = 3
    shadow_edges: str = "cast"
    ambient_occlusion: bool = True
    ao_step: int = 5
    ao_rays: int = 4
    ao_radius_m: float = 2.0
    texture: bool = True
    texture_seed: int = 0
    backend: str = "raycast"
    #: where a device-capable backend (``warp``) runs: ``cpu``, ``cuda`` or ``cuda:N``. Not
    #: a property of the frame (left out of :meth:`to_dict` at its default)
    device: str = "cpu"

    def __post_init__(self) -> None:
        s = object.__setattr__
        for name, (lo, hi) in _PAIRS.items():
            s(self, name, _pair(name, getattr(self, name), lo, hi))
        for p in ("overcast_probability", "wet_probability", "jpeg_probability",
                  "grayscale_probability"):
            s(self, p, probability(f"render config {p}", getattr(self, p)))
        for b in ("shadows", "soft_shadows", "ambient_occlusion", "texture", "wet_reflections"):
            boolean(f"render config {b}", getattr(self, b))
        one_of("render config backend", self.backend, backends.names())
        s(self, "backend", str(self.backend))
        s(self, "device", device_spec(self.device, "render config device"))
        one_of("render config exposure_mode", self.exposure_mode, ("auto", "fixed"))
        one_of("render config randomise", self.randomise, RANDOMISE)
        s(self, "randomise", str(self.randomise))  # a Randomise member is stored as its text
        one_of("render config shadow_edges", self.shadow_edges, SHADOW_EDGES)
        s(self, "shadow_step", integer("render config shadow_step", self.shadow_step, 1, 16))
        s(self, "ao_step", integer("render config ao_step", self.ao_step, 1, 32))
        s(self, "ao_rays", integer("render config ao_rays", self.ao_rays, 1, 64))
        s(self, "ao_radius_m", in_range("render config ao_radius_m", self.ao_radius_m, 0.05,
                                        50.0))
        s(self, "texture_seed", integer("render config texture_seed", self.texture_seed, 0))

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "device" and v == "cpu":
                continue
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    @classmethod
    def preset(cls, name: str = "full", **overrides) -> "RenderConfig":
        """The named preset (:data:`PRESETS`) with keyword overrides."""
        one_of("render preset", name, RENDER_PRESETS)
        return cls(**{**PRESETS[str(name)], **overrides})

    @classmethod
    def from_mapping(cls, data) -> "RenderConfig":
        if not data:
            return cls()
        known_keys("render config", data, [f.name for f in fields(cls)])
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        return cls(**kw)


@dataclass(frozen=True)
class RenderOptions:
    """The render options a command picks by name (validated at construction; a bad value
    raises :class:`ConfigError`): the one home of their defaults.

    preset    : shading preset, a :class:`Preset` value (``"full"``, every realism factor)
    randomise : a :class:`Randomise` value (``"none"``: realistic)
    backend   : a render backend's name (:mod:`.backends`; ``"raycast"``)
    device    : where a device-capable backend runs: ``cpu``, ``cuda`` or ``cuda:N``

    Members of the enums are stored as their text. :meth:`config` is the
    :class:`RenderConfig` they name."""

    preset: str = Preset.FULL.value
    randomise: str = RenderConfig.randomise  # RenderConfig's own default ("none")
    backend: str = RenderConfig.backend
    device: str = RenderConfig.device

    def __post_init__(self) -> None:
        one_of("render preset", self.preset, RENDER_PRESETS)
        one_of("render randomise", self.randomise, RANDOMISE)
        one_of("--backend", self.backend, backends.names())
        object.__setattr__(self, "preset", str(self.preset))
        object.__setattr__(self, "randomise", str(self.randomise))
        object.__setattr__(self, "backend", str(self.backend))
        object.__setattr__(self, "device", device_spec(self.device))

    def config(self, **overrides) -> RenderConfig:
        """The :class:`RenderConfig` of this preset, randomise mode, backend and device, with
        keyword overrides (``shadows``, ...)."""
        return RenderConfig.preset(self.preset, **{"randomise": self.randomise,
                                                   "backend": self.backend,
                                                   "device": self.device, **overrides})

    def check(self) -> None:
        """RenderError (one line) when the backend cannot run here on the device (a missing
        optional dependency, ``cuda`` without CUDA, a device index that does not exist, a
        device for a backend that runs on the CPU only)."""
        b = backends.get(self.backend)
        if self.device != "cpu" and not b.devices:
            raise RenderError(f"--device {self.device}: --backend {self.backend} runs on the "
                              "CPU only; --backend warp runs on a device")
        b.check(self.device)


def sample_factors(cfg: RenderConfig, rng: np.random.Generator) -> dict:
    """Draw every influence factor for one frame (fixed draw order: deterministic).

    Everything drawn is in the returned dict (and so in meta.json), including
    ``pixel_seed``, the seed of the per-pixel hashes (sun-disk samples, ambient-occlusion
    directions, sensor noise)."""
    u = rng.uniform
    f = {
        "sun_azimuth_deg": float(u(*cfg.sun_azimuth_deg)),
        "sun_elevation_deg": float(u(*cfg.sun_elevation_deg)),
        "haze": float(u(*cfg.haze)),
    }
    oc_on, oc = rng.random() < cfg.overcast_probability, float(u(*cfg.overcast))
    f["overcast"] = oc if oc_on else 0.0
    wet_on, wet = rng.random() < cfg.wet_probability, float(u(*cfg.wet))
    f["wet"] = wet if wet_on else 0.0
    f["exposure"] = float(u(*cfg.exposure))
    f["white_balance"] = float(u(*cfg.white_balance))
    f["blur_sigma_px"] = float(u(*cfg.blur_sigma_px))
    f["noise_sigma"] = float(u(*cfg.noise_sigma))
    jp_on, q = rng.random() < cfg.jpeg_probability, int(round(u(*cfg.jpeg_quality)))
    f["jpeg_quality"] = q if jp_on else None
    f["vignetting"] = float(u(*cfg.vignetting))
    f["shadows"] = bool(cfg.shadows)
    f["texture_seed"] = cfg.texture_seed if cfg.texture else None
    # --- realism factors (issue 15), drawn after the original ones
    f["sun_radius_deg"] = float(u(*cfg.sun_radius_deg)) if cfg.soft_shadows else 0.0
    f["haze_tint"] = float(u(*cfg.haze_tint))
    f["exposure_mode"] = cfg.exposure_mode
    f["key_gray"] = float(u(*cfg.key_gray))
    cv, sd_max = float(u(*cfg.contrast_cv)), float(u(*cfg.contrast_sd_max))
    f["contrast_cv"], f["contrast_sd_max"] = cv, sd_max
    f["target_gray_sd"] = min(cv * f["key_gray"], sd_max)
    f["tone_shoulder"] = float(u(*cfg.tone_shoulder))
    f["tint"] = float(u(*cfg.tint))
    f["saturation"] = float(u(*cfg.saturation))
    f["grayscale"] = bool(rng.random() < cfg.grayscale_probability)
    f["chromatic_blur"] = float(u(*cfg.chromatic_blur))
    f["shot_noise"] = float(u(*cfg.shot_noise))
    f["shadow_step"] = cfg.shadow_step
    if cfg.shadow_edges != "cast":  # recorded when not the default (as before otherwise)
        f["shadow_edges"] = cfg.shadow_edges
    f["wet_reflections"] = bool(cfg.wet_reflections)
    f["ambient_occlusion"] = (
        {"step_px": cfg.ao_step, "rays": cfg.ao_rays, "radius_m": cfg.ao_radius_m}
        if cfg.ambient_occlusion else None)
    f["asphalt_albedo"] = float(u(*cfg.asphalt_albedo))
    f["concrete_albedo"] = float(u(*cfg.concrete_albedo))
    f["ground_albedo"] = float(u(*cfg.ground_albedo))
    f["vegetation_dryness"] = float(u(*cfg.vegetation_dryness))
    f["road_wear"] = float(u(*cfg.road_wear)) if cfg.texture else 0.0
    f["sky_light"] = float(u(*cfg.sky_light))
    f["randomise"] = cfg.randomise
    if cfg.randomise == "textures":  # a random colour gain per material, sun and sky
        f["material_rgb_gain"] = np.exp(rng.normal(0.0, 0.6, (len(MATERIALS), 3))).round(
            4).tolist()
        f["sun_rgb"] = rng.uniform(0.6, 1.0, 3).round(4).tolist()
        f["sky_rgb"] = rng.uniform(0.3, 1.0, 3).round(4).tolist()
    f["pixel_seed"] = int(rng.integers(0, 2**62, dtype=np.int64))
    return f
