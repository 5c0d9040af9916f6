"""Per-dataset files of a large export: records are read from meta/ one at a time and the
COCO JSON is written as it is made, with the same bytes as building it whole."""

import json
import random
import weakref

import pytest

from aerial_synth.dataset import aggregate
from aerial_synth.dataset.aggregate import MetaRecords, write_aggregates
from aerial_synth.dataset.export import ExportConfig
from aerial_synth.dataset.layout import meta_path
from aerial_synth.errors import ExportError
from aerial_synth.formats import coco
from aerial_synth.io_utils import StreamedList, atomic_write_chunks, dumps_json, iter_json

from .conftest import small_export as make_small_export

N = 60  # records of the widened export


@pytest.fixture(scope="module")
def small_export(tiny_scene, tmp_path_factory):
    return make_small_export(tmp_path_factory, tiny_scene, "agg", 4, "dota,coco,yolo-obb", 3)


def _widen(cfg, out, dst, n=N):
    """An export of ``n`` images made of copies of ``out``'s 4 (index, name and split set
    as an n-image export would have them)."""
    wide = ExportConfig(**{**{f: getattr(cfg, f) for f in ("scene", "formats", "split", "seed",
                                                            "images_per_placement", "n_vehicles",
                                                            "camera", "simple_vehicles")},
                           "images": n})
    src = [json.loads(meta_path(out, i).read_text()) for i in range(cfg.images)]
    for i in range(n):
        d = dict(src[i % len(src)])
        d["image"] = dict(d["image"], index=i, name=f"{i:06d}", file_name=f"{i:06d}.png",
                          split="train" if i < wide.n_train else "val")
        p = meta_path(dst, i)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(json.dumps(d))
    return wide


def test_streamed_coco_is_the_bytes_of_the_whole_document(small_export, tmp_path):
    cfg, out = small_export
    wide = _widen(cfg, out, tmp_path)
    write_aggregates(wide, tmp_path)
    info = aggregate.dataset_info(wide)
    records = list(MetaRecords(wide, tmp_path))
    for sp in ("train", "val"):
        recs = [r for r in records if r.split == sp]
        images = [coco.CocoImage(r.index + 1, r.file_name, r.width_px, r.height_px) for r in recs]
        objs = [coco.object_from_annotation(a, r.index + 1, r.segmentations[a.vehicle_id])
                for r in recs for a in r.annotations if a.kept and a.box is not None]
        meta = {"description": f"aerial-synth {info.scene} {info.scenario} ({sp})",
                "version": info.tool_version, "seed": info.seed}
        whole = dumps_json(coco.to_dict(images, objs, info.categories, meta))
        assert (tmp_path / f"coco/annotations/instances_{sp}.json").read_text() == whole
        assert len(objs) > N  # many annotations, in several records
    assert json.loads((tmp_path / "summary.json").read_text())["images"] == N


def test_aggregation_holds_a_few_records_at_a_time(small_export, tmp_path, monkeypatch):
    """At most a handful of records alive at once while every aggregate is written (a list
    of every record took ~60 GB for 100,000 images)."""
    cfg, out = small_export
    wide = _widen(cfg, out, tmp_path)
    alive, peak = [0], [0]
    read = MetaRecords.__getitem__

    def counted(self, i):
        r = read(self, i)
        alive[0] += 1
        peak[0] = max(peak[0], alive[0])
        weakref.finalize(r, lambda: alive.__setitem__(0, alive[0] - 1))
        return r

    monkeypatch.setattr(MetaRecords, "__getitem__", counted)
    write_aggregates(wide, tmp_path)
    assert 1 <= peak[0] <= 3, peak[0]


def test_a_foreign_meta_file_is_one_line(small_export, tmp_path):
    cfg, out = small_export
    wide = _widen(cfg, out, tmp_path, n=8)
    d = json.loads(meta_path(tmp_path, 6).read_text())
    d["image"]["split"] = "train"  # image 6 of an 8-image export is a val image
    meta_path(tmp_path, 6).write_text(json.dumps(d))
    with pytest.raises(ExportError, match=r"000006\.json: expected image 6 of split 'val', found image 6 of split 'train'"):
        write_aggregates(wide, tmp_path)
    assert not (tmp_path / "coco/annotations/instances_val.json").exists()
    assert [p.name for p in (tmp_path / "coco/annotations").iterdir() if p.name.startswith(".")] == []


def _random_json(rng, depth=0):
    t = rng.random()
    if depth > 3 or t < 0.3:
        return rng.choice([0, -7, 2.5, 1e-9, "a\nb", "é\u2603", None, True, False, ""])
    if t < 0.6:
        return [_random_json(rng, depth + 1) for _ in range(rng.randint(0, 3))]
    return {rng.choice("abcxyz") + str(k): _random_json(rng, depth + 1) for k in range(rng.randint(0, 3))}


def _streamed(obj, rng):
    """``obj`` with some lists (those reachable through dicts and streamed lists) streamed."""
    if isinstance(obj, list) and rng.random() < 0.6:
        return StreamedList(iter([_streamed(x, rng) for x in obj]))
    if isinstance(obj, dict):
        return {k: _streamed(v, rng) for k, v in obj.items()}
    return obj


def test_iter_json_is_dumps_json():
    rng = random.Random(5)
    for _ in range(500):
        obj = _random_json(rng)
        assert "".join(iter_json(_streamed(obj, rng))) == dumps_json(obj)
    assert "".join(iter_json(StreamedList(iter([])))) == "[]\n"
    assert "".join(iter_json({"a": StreamedList(iter([])), "b": {}})) == dumps_json({"a": [], "b": {}})


def test_chunked_write_failing_midway_keeps_the_old_file(tmp_path):
    target = tmp_path / "x.json"
    target.write_text("old\n")

    def chunks():
        yield "new, part 1\n"
        raise RuntimeError("made up")

    with pytest.raises(RuntimeError):
        atomic_write_chunks(target, chunks())
    assert target.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["x.json"]
    atomic_write_chunks(target, iter(["a", b"b", "\u2603"]))
    assert target.read_text(encoding="utf-8") == "ab\u2603"
