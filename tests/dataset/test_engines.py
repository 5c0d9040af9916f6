"""Engines behind one interface: chosen in one place, and a toy engine registered at run
time exports the very bytes of the serial engine with no change to the exporter."""

import warnings

import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset import engines
from aerial_synth.dataset.engines.dask import DaskEngine
from aerial_synth.dataset.engines.pool import PoolEngine
from aerial_synth.dataset.engines.serial import SerialEngine
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError

from .conftest import tree_bytes
from .tiny_engine import ReverseEngine


def test_choose_is_the_one_place():
    assert engines.names()[:3] == ("serial", "pool", "dask")
    assert type(engines.choose()) is SerialEngine and type(engines.choose(1)) is SerialEngine
    pool = engines.choose(3)
    assert type(pool) is PoolEngine and pool.workers == 3 and pool.local_processes == 3
    d = engines.choose(None, "local:2")
    assert type(d) is DaskEngine and d.local_processes == 2
    assert engines.choose(None, "tcp://h:8786").local_processes is None  # the cluster's, elsewhere
    with pytest.raises(ExportError, match="--dask and --workers: choose one engine"):
        engines.choose(1, "local:2")
    with pytest.raises(ExportError, match="unknown engine 'ray'; expected one of serial, pool, dask"):
        engines.choose(engine="ray")
    with pytest.raises(ExportError, match="already registered"):
        engines.register(SerialEngine)


@pytest.fixture
def toy_engine():
    engines.register(ReverseEngine)
    ReverseEngine.seen = []
    yield ReverseEngine
    engines.unregister(ReverseEngine.name)


def test_toy_engine_exports_the_serial_bytes(tiny_scene, tmp_path, toy_engine):
    with warnings.catch_warnings():  # open3d's import warns once per process (a CUDA build
        warnings.simplefilter("ignore")  # without a GPU); the first placement group would
        import open3d  # noqa: F401          record it: import it before either export
    cfg = ExportConfig(scene=tiny_scene, images=4, formats="dota,yolo-obb", split=0.5, seed=5,
                       images_per_placement=2, n_vehicles=8,
                       camera=CameraConfig(width_px=96, height_px=96),
                       simple_vehicles=True)
    export_dataset(cfg, tmp_path / "serial", progress=False)
    res = export_dataset(cfg, tmp_path / "toy", engine="toy-reverse", progress=False)
    assert res.rendered == 4 and ReverseEngine.seen == [[2, 3], [0, 1]]  # it ran, backwards
    a, b = tree_bytes(tmp_path / "serial"), tree_bytes(tmp_path / "toy")
    assert any(k.endswith(".txt") and "labelTxt" in k for k in a)
    assert a.keys() == b.keys() and [k for k in a if a[k] != b[k]] == []
