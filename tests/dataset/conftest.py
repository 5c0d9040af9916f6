import pytest

from ..helpers import REPO, run_cli, tree_bytes, write_crossing_obj

__all__ = ["REPO", "run_cli", "tree_bytes", "small_export"]


@pytest.fixture(scope="session")
def tiny_scene(tmp_path_factory) -> str:
    """An 80 m x 80 m hand-built scene: grass and a crossing of two 8 m roads (OBJ)."""
    return write_crossing_obj(tmp_path_factory.mktemp("scene") / "tiny.obj", 40)


def small_export(tmp_path_factory, tiny_scene: str, name: str, images: int, formats: str, seed: int):
    """A tiny 1-worker export on ``tiny_scene`` (128 px frames, box vehicles, 2 images per
    placement, half train): (config, its folder)."""
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    out = tmp_path_factory.mktemp(name) / "ds"
    cfg = ExportConfig(scene=tiny_scene, images=images, formats=formats, split=0.5, seed=seed,
                       images_per_placement=2, n_vehicles=10,
                       camera=CameraConfig(width_px=128, height_px=128),
                       simple_vehicles=True)
    export_dataset(cfg, out, workers=1, progress=False)
    return cfg, out
