"""One image of an export, in memory: :func:`render_sample` ``(plan, i)`` -> :class:`Sample`.

``render_sample`` does no I/O and its result depends only on (plan, i): export (its engines
and writers), the stream (:mod:`aerial_synth.stream`) and the ``render`` command all call it,
so an image is the same whichever of them made it.

What it memoises, per process, is not observable in its results: loaded scenes
(:func:`load_export_scene`, keyed by what loads them), the catalog, and the current
placement group of each recent plan (:class:`SampleRenderer`, keyed by (plan, group)). A
group's RayScene is built fresh, its placement drawn from the group's own seed, and its
cameras are those of every image of the group (drawn before the vehicles are added, whatever
images of it are asked for), so neither the order of the calls nor how images are split
between processes changes a byte.

The backend that makes the frame is the render config's (``plan.render.backend``, looked up
in :mod:`aerial_synth.render.backends` by :func:`~aerial_synth.render.render_frame`).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..annotate.boxes import annotate_frame
from ..errors import ExportError, own_warnings
from ..formats import coco, meta
from ..formats.labels import ImageLabels
from ..formats.registry import get as get_format
from ..placement import place
from ..render import add_placement, render_frame
from ..render.cull import vehicles_for_views
from ..scene.raycast import RayScene
from ..vehicles import load_catalog
from .config import PLACEMENT_STREAM, ExportConfig
from .layout import image_name, split_of
from .plan import ExportPlan, build_plan
from .scenes import load_export_scene, scene_distractors, scene_georeference

__all__ = ["Sample", "SampleRenderer", "load_export_scene", "render_sample", "renderer_for",
           "scene_distractors", "scene_georeference"]

@dataclass(frozen=True)
class Sample:
    """One rendered and annotated image.

    index  : the image's index in its plan
    rgb    : (H, W, 3) uint8, RGB order: the pixels export encodes
    labels : the kept boxes (pixels, image frame), classes and difficult flags, the GSD and
             the size: :class:`~aerial_synth.formats.labels.ImageLabels`
    meta   : the image's full record (:class:`~aerial_synth.formats.meta.ImageRecord`): what
             export writes to ``meta/<name>.json`` and every format writes its labels from
    frame  : the renderer's :class:`~aerial_synth.render.frame.Frame` (instance, semantic and
             depth buffers) when asked for (``render_sample(..., frame=True)``), else None
    """

    index: int
    rgb: np.ndarray
    labels: ImageLabels
    meta: meta.ImageRecord
    frame: object | None = field(default=None, repr=False, compare=False)

    def label_text(self, fmt: str) -> str | None:
        """The per-image label file format ``fmt`` writes for this image (None: the format
        has no per-image file)."""
        return get_format(fmt).label_text(self.meta)


def labels_of(record: meta.ImageRecord) -> ImageLabels:
    """The kept annotations of ``record`` as :class:`ImageLabels` (vehicle-id order)."""
    kept = [a for a in record.annotations if a.kept and a.box is not None]
    poly = np.array([np.asarray(a.box.corners, dtype=np.float64).reshape(4, 2) for a in kept],
                    dtype=np.float64).reshape(-1, 4, 2)
    return ImageLabels(record.name, poly, [a.cls for a in kept], np.array([a.difficult for a in kept], bool),
                       gsd_m=float(record.gsd_m), size_wh=(int(record.width_px), int(record.height_px)))


# ------------------------------------------------------------------ placement groups


@dataclass
class Group:
    """A placement group ready to render: its RayScene (with the vehicles some camera of the
    group can see), placement, every image's camera, and what the metadata says of it."""

    index: int
    rayscene: RayScene
    placement: object
    cameras: dict
    within_xy: np.ndarray
    warnings: list
    georeference: dict
    mix: dict | None = None


class SampleRenderer:
    """The per-process memo of one plan: catalog, scenes and the current placement group.
    ``scene``/``catalog``: already loaded ones (an engine hands its workers the parent's)."""

    def __init__(self, plan: ExportPlan, nthreads: int = 0, scene=None, catalog=None):
        self.plan = plan
        self.nthreads = nthreads
        self._catalog = catalog
        self._group: Group | None = None
        self._grid = None  # a tiled export's tile grid
        self._placer = None  # a tiled export's GroupPlacer
        self._window = None  # (rect, Scene): a tiled export's last render window
        if scene is not None:  # the first group's scene (the export's, or a mix's first entry)
            load_export_scene(plan.scenes.scene_config(0), keep=scene)

    @property
    def catalog(self):
        if self._catalog is None:
            self._catalog = load_catalog()
        return self._catalog

    def scene(self, group: int = 0):
        return self.plan.scenes.scene_for_group(group)

    @property
    def grid(self):
        """A tiled export's tile grid (one per renderer)."""
        if self._grid is None:
            self._grid = self.scene(0).grid(self.plan.cfg.tile_m, self.plan.cfg.margin_m)
        return self._grid

    # -- groups ------------------------------------------------------------------------
    def group(self, g: int) -> Group:
        """Placement group ``g``, set up once (the previous group is dropped)."""
        if self._group is not None and self._group.index == g:
            return self._group
        self._group = None  # the old group's Embree scene goes before the next is built
        place_group = self._tiled_group if self.plan.scenes.kind == "tiled" else self._plain_group
        rs, pl, within, warned, geo, mix = place_group(g)
        cameras = {i: self.plan.camera.camera_for(i, within, pl, clear=lambda c: self._open_sky(rs, c))
                   for i in self.plan.group_indices(g)}
        add_placement(rs, self._visible_part(rs, pl, cameras), self.catalog,
                      simple_boxes=self.plan.cfg.simple_vehicles)
        self._group = Group(g, rs, pl, cameras, within, warned, geo, mix)
        return self._group

    def _open_sky(self, rs, cam) -> bool:
        """Whether nothing solid is above ``cam`` in the group's scene
        (:meth:`~aerial_synth.scene.raycast.RayScene.open_above`): a camera inside or under a
        building would render the building's inside, so it is redrawn."""
        return rs.open_above(cam.center)

    def _plain_group(self, g: int):
        cfg = self.plan.cfg
        entry = self.plan.scenes.entry_for_group(g)
        scene = self.scene(g)
        rs = RayScene(scene, nthreads=self.nthreads)  # fresh: independent of history
        rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, g, PLACEMENT_STREAM]))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pl = place(rs, entry.scenario, rng, n_vehicles=cfg.n_vehicles, n_lines=cfg.n_lines,
                       catalog=self.catalog, scene_name=scene.name)
        if not pl.vehicles:
            where = scene.name if entry.mix is not None else repr(cfg.scene)
            raise ExportError(f"placement group {g}: scenario {entry.scenario!r} placed no vehicles "
                              f"on scene {where} (no road found?)")
        within = scene.bounds()[:, :2]
        return rs, pl, within, sorted(set(own_warnings(caught))), scene_georeference(scene), entry.mix

    def _tiled_group(self, g: int):
        from .tiled import GroupPlacer, group_placement, grow_rect

        cfg = self.plan.cfg
        world = self.scene(g)
        grid = self.grid
        if self._placer is None:
            self._placer = GroupPlacer(world, grid, cfg, self.catalog)
        tile, within, _area, pl, warned = group_placement(world, grid, cfg, g, self.catalog, self._placer)
        if not pl.vehicles:
            raise ExportError(f"placement group {g}: scenario {cfg.scenario!r} placed no "
                              f"vehicles near tile {list(tile.key)} of scene {cfg.scene!r}")
        rect = grow_rect(within, self._placer.pads.render_m, grid.bounds)
        if self._window is None or self._window[0] != rect:
            self._window = None  # drop the old window before building the next
            self._window = (rect, world.scene_for(rect))
        rs = RayScene(self._window[1], nthreads=self.nthreads)  # fresh: independent of history
        x0, y0, x1, y1 = within
        return rs, pl, np.array([[x0, y0], [x1, y1]]), warned, world.georeference(), None

    def _visible_part(self, rs, pl, cameras):
        """``pl`` with only the vehicles some camera of the group can see in ``rs``'s scene,
        directly, in a shadow or a reflection (:func:`~aerial_synth.render.cull.vehicles_for_views`):
        the group's Embree scenes and meshes are built for those only."""
        kept = vehicles_for_views(pl.vehicles, cameras.values(), self.plan.render,
                                  z_low=float(rs.scene.bounds()[0, 2]))
        return pl if len(kept) == len(pl.vehicles) else dataclasses.replace(pl, vehicles=kept)

    # -- images ------------------------------------------------------------------------
    def sample(self, index: int, frame: bool = False) -> Sample:
        """Render and annotate image ``index`` (see :func:`render_sample`)."""
        plan, cfg = self.plan, self.plan.cfg
        index = int(index)
        if not 0 <= index < cfg.images:
            raise ExportError(f"image {index}: the plan has images 0..{cfg.images - 1}")
        group = plan.group_of(index)
        grp = self.group(group)
        pl, rs = grp.placement, grp.rayscene
        _, render_ss = np.random.SeedSequence([cfg.seed, index]).spawn(2)
        cam = grp.cameras[index]
        fr = render_frame(rs, cam, pl, np.random.default_rng(render_ss), config=plan.render)
        H, W = fr.instance.shape
        segs = {}

        def sink(vid, crop, off):
            segs[vid] = coco.rle_from_crop(crop, off, H, W)

        anns = annotate_frame(fr, cam, pl, plan.box, mask_sink=sink)
        by_id = pl.by_id()
        name = image_name(index)
        render_meta = fr.to_meta()
        render_meta.pop("vehicles", None)  # per-vehicle visibility is in ``vehicles``
        render_meta.pop("camera", None)
        rec = meta.ImageRecord(
            index=index,
            name=name,
            file_name=f"{name}.{cfg.image_ext}",
            split=split_of(cfg, index),
            width_px=W,
            height_px=H,
            gsd_m=float(getattr(cam, "gsd_m", plan.camera.widest.nadir_gsd_m)),
            seed={
                "dataset_seed": cfg.seed,
                "image_index": index,
                "image_entropy": [cfg.seed, index],
                "placement_group": group,
                "placement_entropy": [cfg.seed, group, PLACEMENT_STREAM],
            },
            camera=cam.to_dict(),
            render=render_meta,
            placement={
                "scene": pl.scene,
                "scenario": pl.scenario,
                "parameters": pl.parameters,
                "n_vehicles": len(pl.vehicles),
                "warnings": grp.warnings,
                # scenes with hard negatives (procedural/negatives.py) count them here
                **({"hard_negatives": rs.scene.hints.negatives.to_dict()}
                   if rs.scene.hints.negatives is not None else {}),
                **({"scene_mix": dict(grp.mix)} if grp.mix is not None else {}),
            },
            box_config=plan.box.to_dict(),
            annotations=tuple(anns),
            world={a.vehicle_id: by_id[a.vehicle_id].to_dict() for a in anns},
            segmentations=segs,
            georeference=grp.georeference,
        )
        return Sample(index, fr.rgb, labels_of(rec), rec, fr if frame else None)


# ------------------------------------------------------------------------ the function

_RENDERERS: OrderedDict = OrderedDict()  # plan -> SampleRenderer, this process
_MAX_RENDERERS = 4


def renderer_for(plan: ExportPlan, nthreads: int = 0, scene=None, catalog=None) -> SampleRenderer:
    """This process's :class:`SampleRenderer` of ``plan`` (the last few plans are kept)."""
    r = _RENDERERS.get(plan)
    if r is None:
        r = _RENDERERS[plan] = SampleRenderer(plan, nthreads=nthreads, scene=scene, catalog=catalog)
        while len(_RENDERERS) > _MAX_RENDERERS:
            _RENDERERS.popitem(last=False)
    _RENDERERS.move_to_end(plan)
    return r


def render_sample(plan: ExportPlan | ExportConfig, index: int, *, frame: bool = False) -> Sample:
    """Image ``index`` of ``plan`` (an :class:`ExportPlan`, or an ExportConfig to build one
    from): its RGB pixels, labels and metadata, exactly as export writes them; no I/O.
    ``frame``: also keep the renderer's buffers (``Sample.frame``)."""
    if isinstance(plan, ExportConfig):
        plan = build_plan(plan)
    return renderer_for(plan).sample(index, frame=frame)
