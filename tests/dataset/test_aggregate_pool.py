"""Aggregate files read on a process pool (``MetaRecords.map``): the same bytes for any
worker count, each meta file read once, errors as one line with no process left behind,
and a bounded number of chunks in flight."""

import dataclasses
import json
import multiprocessing
import operator
import random
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import pytest

from aerial_synth.dataset import aggregate
from aerial_synth.dataset.aggregate import MetaRecords, summarise, write_aggregates
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.dataset.layout import meta_path
from aerial_synth.dataset.worker import record_counts
from aerial_synth.errors import ExportError, LabelFormatError
from aerial_synth.formats import CATEGORIES, registry
from aerial_synth.formats.registry import LabelFormat

from ..helpers import REPO, tree_bytes
from .conftest import small_export as make_small_export

N = 24  # records of a widened export: several chunks per worker once the thresholds are lowered


@pytest.fixture(scope="module")
def small_export(tiny_scene, tmp_path_factory):
    return make_small_export(tmp_path_factory, tiny_scene, "aggpool", 6, "dota,eagle,yolo-obb,coco", 5)


@pytest.fixture
def pool_for_all(monkeypatch):
    """Every pass of two records or more goes to the pool (when workers > 1)."""
    monkeypatch.setattr(aggregate, "POOL_MIN_RECORDS", 1)
    monkeypatch.setattr(aggregate, "PASS_MIN_RECORDS", 1)


def _widen(cfg, out, dst, n=N, split=None, no_vehicles=()):
    """An export of ``n`` images made of copies of ``out``'s meta files (index, name and split
    set as an n-image export would have them); the images ``no_vehicles`` have none."""
    fields = ("scene", "formats", "split", "seed", "images_per_placement", "n_vehicles", "camera",
              "simple_vehicles")
    wide = ExportConfig(**{**{f: getattr(cfg, f) for f in fields}, "images": n,
                           **({} if split is None else {"split": split})})
    src = [json.loads(meta_path(out, i).read_text()) for i in range(cfg.images)]
    for i in range(n):
        d = dict(src[i % len(src)])
        d["image"] = dict(d["image"], index=i, name=f"{i:06d}", file_name=f"{i:06d}.png",
                          split="train" if i < wide.n_train else "val")
        if i in no_vehicles:
            d["vehicles"], d["counts"] = [], {"kept": 0, "difficult": 0, "dropped": 0}
        p = meta_path(dst, i)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(json.dumps(d))
    return wide


def _aggregates(root) -> dict:
    return {k: v for k, v in tree_bytes(root).items() if not k.startswith("meta")}


def _old_summary(cfg, records) -> dict:
    """summary.json's counts as they were made before the pool: a second pass, in order."""
    classes, reasons = {c: 0 for c in CATEGORIES}, {}
    tot = {"difficult": 0, "dropped": 0, "kept": 0}
    unclear = 0
    for r in records:
        c = record_counts(r)
        for k, n in c["classes"].items():
            classes[k] = classes.get(k, 0) + n
        for k, n in c["dropped_reasons"].items():
            reasons[k] = reasons.get(k, 0) + n
        for k in tot:
            tot[k] += c[k]
        unclear += sum(1 for a in r.annotations if a.kept and a.orientation_unclear)
    return {"vehicles_kept": tot["kept"], "vehicles_per_class": classes, "difficult": tot["difficult"],
            "orientation_unclear": unclear, "dropped": tot["dropped"], "dropped_reasons": dict(sorted(reasons.items()))}


@pytest.mark.parametrize("case", ["two splits", "no val images", "val without annotations"])
def test_any_worker_count_writes_the_same_bytes(small_export, tmp_path, pool_for_all, monkeypatch, case):
    cfg, out = small_export
    kw = {"two splits": {}, "no val images": {"split": 1.0},
          "val without annotations": {"no_vehicles": range(N // 2, N)}}[case]
    pools = []
    real = MetaRecords._map_pool
    monkeypatch.setattr(MetaRecords, "_map_pool", lambda self, fn, chunks, split, workers: (
        pools.append(workers), real(self, fn, chunks, split, workers))[1])
    got = {}
    for w in (1, 2, 3):
        wide = _widen(cfg, out, tmp_path / str(w), **kw)
        pools.clear()
        summary = write_aggregates(wide, tmp_path / str(w), workers=w)
        assert pools == ([] if w == 1 else [w] * len(pools)) and (w == 1 or pools), (w, pools)
        got[w] = _aggregates(tmp_path / str(w))
        records = list(MetaRecords(wide, tmp_path / str(w)))
        old = _old_summary(wide, records)
        assert {k: summary[k] for k in old} == old
        assert list(summary["vehicles_per_class"]) == list(old["vehicles_per_class"])
        assert summarise(wide, records) == summary  # a plain list of records: same summary
        for rel, body in registry.get("coco").aggregate_files(records, aggregate.dataset_info(wide)).items():
            assert "".join(body).encode() == (tmp_path / str(w) / rel).read_bytes()  # and same COCO
    assert got[1] == got[2] == got[3]
    names = set(got[1])
    assert "coco/annotations/instances_train.json" in names and "summary.json" in names
    assert ("coco/annotations/instances_val.json" in names) == (case != "no val images")
    if case == "val without annotations":
        val = json.loads(got[1]["coco/annotations/instances_val.json"])
        assert val["annotations"] == [] and len(val["images"]) == N // 2
    else:
        assert json.loads(got[1]["summary.json"])["vehicles_kept"] > 0


def test_each_meta_file_is_read_once(small_export, tmp_path, monkeypatch):
    """COCO's passes count the records for summary.json; without COCO, the summary's pass
    is the only one."""
    cfg, out = small_export
    reads = []
    real = MetaRecords.__getitem__
    monkeypatch.setattr(MetaRecords, "__getitem__", lambda self, i: (reads.append(i), real(self, i))[1])
    wide = _widen(cfg, out, tmp_path / "a")
    ref = write_aggregates(wide, tmp_path / "a", workers=1)
    assert sorted(reads) == list(range(N))
    reads.clear()
    no_coco = dataclasses.replace(wide, formats="dota,yolo-obb")
    _widen(cfg, out, tmp_path / "b")
    other = write_aggregates(no_coco, tmp_path / "b", workers=1)
    assert sorted(reads) == list(range(N))
    assert {k: v for k, v in other.items() if k != "formats"} == {k: v for k, v in ref.items() if k != "formats"}


class _RereadFormat(LabelFormat):
    """Reads every record again after COCO has: by ``map`` and by iterating."""

    name = "reread"

    def aggregate_files(self, records, info):
        indices = list(records.map(operator.attrgetter("index")))
        kept = sum(1 for r in records for a in r.annotations if a.kept)
        return {f"{self.folder}/reread.txt": f"{indices == list(range(len(records)))} {kept}\n"}


@pytest.mark.parametrize("workers", [1, 2])
def test_records_read_twice_are_counted_once(small_export, tmp_path, pool_for_all, workers):
    cfg, out = small_export
    wide = _widen(cfg, out, tmp_path / "ref")
    ref = write_aggregates(wide, tmp_path / "ref", workers=workers)
    fmt = registry.register(_RereadFormat())
    try:
        twice = dataclasses.replace(wide, formats=(*wide.formats, "reread"))
        _widen(cfg, out, tmp_path / "twice")
        got = write_aggregates(twice, tmp_path / "twice", workers=workers)
    finally:
        registry.unregister(fmt.name)
    assert (tmp_path / "twice/reread/reread.txt").read_text() == f"True {ref['vehicles_kept']}\n"
    assert {**got, "formats": ref["formats"]} == ref


def test_summary_counts_do_not_depend_on_the_order_records_arrive():
    rng = random.Random(3)
    tallies = []
    for i in range(40):
        classes = [(c, rng.randint(1, 3)) for c in rng.sample([*CATEGORIES, "tank", "cart"], 3)]
        reasons = [(r, 1) for r in rng.sample(["occluded", "small", "edge"], 2)]
        tallies.append((i, (tuple(classes), tuple(reasons), 1, 2, 3, i % 2)))
    ref = aggregate._Tally()
    for i, t in tallies:
        ref.add(i, t)
    assert list(ref.vehicles_per_class())[len(CATEGORIES):] in (["tank", "cart"], ["cart", "tank"])
    for _ in range(5):
        rng.shuffle(tallies)
        got = aggregate._Tally()
        for i, t in tallies:
            got.add(i, t)
        assert list(got.vehicles_per_class().items()) == list(ref.vehicles_per_class().items())
        assert (got.reasons, got.kept, got.unclear) == (ref.reasons, ref.kept, ref.unclear)


def _error(wide, root, workers):
    with pytest.raises((ExportError, OSError)) as info:
        write_aggregates(wide, root, workers=workers)
    return info.value


@pytest.mark.parametrize("damage", ["foreign", "corrupt", "missing"])
def test_a_bad_meta_file_is_the_same_one_line_through_the_pool(small_export, tmp_path, pool_for_all, damage):
    cfg, out = small_export
    errors = {}
    for w in (1, 2):
        root = tmp_path / str(w)
        wide = _widen(cfg, out, root)
        p = meta_path(root, 20)  # a val image, in a later chunk
        if damage == "foreign":
            d = json.loads(p.read_text())
            d["image"]["split"] = "train"
            p.write_text(json.dumps(d))
        elif damage == "corrupt":
            p.write_text('{"format": "aerial-synth-image-meta", "image": {')
        else:
            p.unlink()
        exc = _error(wide, root, w)
        assert multiprocessing.active_children() == []
        assert exc.__cause__ is None and exc.__suppress_context__ or w == 1
        errors[w] = (type(exc), str(exc).replace(str(tmp_path / str(w)), "ROOT"))
        assert not (root / "coco/annotations/instances_val.json").exists()
        assert not [q for q in (root / "coco/annotations").iterdir() if q.name.startswith(".")]
    assert errors[1] == errors[2], errors
    kind, text = errors[1]
    assert "\n" not in text and "000020.json" in text
    # a missing file is the project's one-line error too (safe_input.read_bytes), not an OSError
    assert kind is {"foreign": ExportError, "corrupt": LabelFormatError, "missing": LabelFormatError}[damage]
    if damage == "foreign":
        assert "expected image 20 of split 'val', found image 20 of split 'train'" in text


def test_the_pool_holds_a_window_of_chunks(small_export, tmp_path, pool_for_all, monkeypatch):
    """Chunks are submitted as results are used, not all at once (an unbounded backlog)."""
    cfg, out = small_export
    n = 60
    wide = _widen(cfg, out, tmp_path, n=n)
    submitted = []
    real = ProcessPoolExecutor.submit
    monkeypatch.setattr(ProcessPoolExecutor, "submit",
                        lambda self, fn, *a: (submitted.append(len(a[-1])), real(self, fn, *a))[1])
    records = MetaRecords(wide, tmp_path, workers=2)
    ahead = []
    for k, index in enumerate(records.map(operator.attrgetter("index"))):
        assert index == k
        ahead.append(sum(submitted) - (k + 1))
    chunk = max(submitted)
    assert len(submitted) > aggregate.WINDOW_PER_WORKER * 2  # several windows' worth
    # while a chunk is used, the window's other chunks and its replacement are in flight
    assert max(ahead) <= (aggregate.WINDOW_PER_WORKER * 2 + 1) * chunk - 1 < n - 1, (max(ahead), chunk)
    assert multiprocessing.active_children() == []
    assert summarise(wide, records)["images"] == n and records._counted == bytearray([1]) * n


_UNGUARDED = """
import sys
from aerial_synth.dataset import aggregate
from aerial_synth.dataset.export import ExportConfig
aggregate.POOL_MIN_RECORDS = aggregate.PASS_MIN_RECORDS = 1
cfg = ExportConfig.from_dict({CFG})
aggregate.write_aggregates(cfg, sys.argv[1], workers=2)
print("written in", __name__)
"""


def test_a_script_without_a_main_guard_still_gets_its_files(small_export, tmp_path):
    """Its pool processes would run the script again: they stop at once, and the parent
    makes the files itself, with a warning."""
    cfg, out = small_export
    wide = _widen(cfg, out, tmp_path / "ref")
    write_aggregates(wide, tmp_path / "ref", workers=1)
    _widen(cfg, out, tmp_path / "script")
    script = tmp_path / "export_script.py"
    script.write_text(_UNGUARDED.replace("{CFG}", repr(wide.to_dict())))
    env = {"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}
    res = subprocess.run([sys.executable, str(script), str(tmp_path / "script")], capture_output=True,
                         text=True, timeout=120, env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == "written in __main__"
    assert "a worker process died" in res.stderr and "must guard its entry point" in res.stderr
    assert "Traceback" not in res.stderr  # the stopped pool processes leave quietly
    assert _aggregates(tmp_path / "script") == _aggregates(tmp_path / "ref")


_UNGUARDED_EXPORT = """
import sys
from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError
cfg = ExportConfig(scene="city_park", scenario="jam", images=4, formats="dota",
                   camera=CameraConfig(width_px=64, height_px=64))
try:
    export_dataset(cfg, sys.argv[1], workers=2, force=True, progress=False)
except ExportError as exc:
    if __name__ != "__main__":  # a worker running this script again: no handler of its own
        raise
    print("refused:", exc)
    sys.exit(2)
"""


def test_an_unguarded_script_exporting_on_workers_is_refused_without_worker_tracebacks(tmp_path):
    script = tmp_path / "export_script.py"
    script.write_text(_UNGUARDED_EXPORT)
    env = {"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}
    res = subprocess.run([sys.executable, str(script), str(tmp_path / "out")], capture_output=True,
                         text=True, timeout=180, env=env)
    assert res.returncode == 2, res.stderr[-2000:]
    assert res.stdout.count("refused:") == 1 and "must guard its entry point" in res.stdout
    assert "Traceback" not in res.stderr, res.stderr[-2000:]
    assert not (tmp_path / "out").exists()


def test_an_export_aggregating_on_the_pool_is_the_same_export(small_export, tmp_path, pool_for_all, monkeypatch):
    """export_dataset with the thresholds lowered: the fork server started early, the
    aggregates made on the pool, every file as before."""
    from aerial_synth.dataset import export
    from aerial_synth.dataset.engines.affinity import allowed_cores

    if len(allowed_cores()) < 2:
        pytest.skip("one core: the default is no pool")
    cfg, out = small_export
    started, pools = [], []
    real_start, real_pool = export.start_pool_server, MetaRecords._map_pool
    monkeypatch.setattr(export, "start_pool_server", lambda *a, **k: (started.append(a), real_start(*a, **k))[1])
    monkeypatch.setattr(MetaRecords, "_map_pool", lambda self, fn, chunks, split, workers: (
        pools.append(workers), real_pool(self, fn, chunks, split, workers))[1])
    export_dataset(cfg, tmp_path / "ds", workers=1, progress=False)
    assert started == [()] and pools
    a, b = tree_bytes(out), tree_bytes(tmp_path / "ds")
    assert a.keys() == b.keys() and [k for k in a if a[k] != b[k]] == []


@pytest.mark.parametrize("good_submits", [0, 3])
def test_a_pool_that_breaks_while_chunks_are_submitted(small_export, tmp_path, pool_for_all,
                                                        monkeypatch, good_submits):
    """The pool may break between two results, so that the next submit raises
    BrokenProcessPool (seen in a loaded clean-clone run: a traceback instead of the files).
    The refused chunk and the rest are then made in this process, in order: the same bytes,
    with the one warning."""
    from concurrent.futures.process import BrokenProcessPool

    cfg, out = small_export
    wide = _widen(cfg, out, tmp_path / "ref")
    write_aggregates(wide, tmp_path / "ref", workers=1)
    _widen(cfg, out, tmp_path / "broken")
    real_submit, calls = ProcessPoolExecutor.submit, []

    def submit(self, *a, **kw):
        calls.append(1)
        if len(calls) > good_submits:
            raise BrokenProcessPool("a child process terminated abruptly")
        return real_submit(self, *a, **kw)

    monkeypatch.setattr(ProcessPoolExecutor, "submit", submit)
    with pytest.warns(RuntimeWarning, match="a worker process died"):
        write_aggregates(wide, tmp_path / "broken", workers=2)
    assert len(calls) > good_submits
    assert _aggregates(tmp_path / "broken") == _aggregates(tmp_path / "ref")
