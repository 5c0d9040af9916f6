"""Reliability, round 3 (issue 37): one test per cause of the hostile-input failures found at
3deb0c2, written from the issue. Each runs the command as a user would (``main(argv)`` in
process, or the console script in a subprocess where a hang, a signal or memory is the point)
and asserts: one line on stderr, exit status 2 (or the conventional signal status), no
traceback, no file's content quoted, nothing written or replaced that should not be."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from aerial_synth.cli import main
from tests.evaluate.conftest import make_dota
from tests.helpers import REPO, one_line, tree_bytes, write_crossing_obj

SECRET = "root:$6$s3cr3tHASHvalue:19000:0:99999:7:::"


def run(capsys, *argv):
    """(exit status, stderr) of ``aerial-synth ARGV`` run in this process."""
    code = main([a if isinstance(a, str) else os.fsdecode(a) if isinstance(a, (bytes, os.PathLike)) else str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.err


def cli(*argv, timeout=60, cwd=None, env=None, **kw):
    """The console entry point in its own process (crashes, hangs, signals, memory)."""
    e = dict(os.environ, PYTHONPATH=str(REPO), **(env or {}))
    return subprocess.run([sys.executable, "-m", "aerial_synth.cli", *map(os.fsdecode, argv)],
                          capture_output=True, timeout=timeout, cwd=cwd, env=e, **kw)


@pytest.fixture
def secret(tmp_path):
    p = tmp_path / "shadow"
    p.write_text(SECRET + "\n")
    return p


@pytest.fixture
def mesh_dir(tmp_path, secret):
    """sc/town.obj with sc/town.labels.yaml a link to a file outside sc/ (issue 37 D1)."""
    sc = tmp_path / "sc"
    sc.mkdir()
    write_crossing_obj(sc / "town.obj", 40)
    (sc / "town.labels.yaml").symlink_to(secret)
    return sc


# -- D1, D2: disclosure ----------------------------------------------------------------------


def test_d1_sidecar_label_rules_link_out_of_folder(capsys, tmp_path, mesh_dir):
    err = one_line(*run(capsys, "scene", "show", mesh_dir / "town.obj", "--out", tmp_path / "m.png"))
    assert "outside its folder" in err and "town.labels.yaml" in err
    assert "s3cr3t" not in err and "root:" not in err
    assert not (tmp_path / "m.png").exists()


def test_d1_sidecar_through_python_api_and_scene_mix(capsys, tmp_path, mesh_dir):
    from aerial_synth.errors import SceneError
    from aerial_synth.scene.io import load_scene

    with pytest.raises(SceneError) as e:
        load_scene(str(mesh_dir / "town.obj"))
    assert "s3cr3t" not in str(e.value) and "outside its folder" in str(e.value)
    err = one_line(*run(capsys, "export", "--scene-mix", f"{mesh_dir / 'town.obj'}:1", "--images", 1,
                        "--out", tmp_path / "ds"))
    assert "s3cr3t" not in err and "outside its folder" in err
    assert not (tmp_path / "ds").exists()


def test_d1_sidecar_inside_folder_still_read(tmp_path):
    from aerial_synth.scene.io import load_scene

    sc = tmp_path / "sc"
    sc.mkdir()
    write_crossing_obj(sc / "town.obj", 40)
    (tmp_path / "rules.yaml").write_text("rules:\n  road*: road\n")
    (sc / "town.labels.yaml").symlink_to("../rules.yaml")  # out of sc/: refused
    with pytest.raises(Exception, match="outside its folder"):
        load_scene(str(sc / "town.obj"))
    (sc / "town.labels.yaml").unlink()
    (sc / "real.yaml").write_text("rules:\n  road*: road\n  ground: water\n")
    (sc / "town.labels.yaml").symlink_to("real.yaml")  # a link inside sc/: read
    assert {o.label for o in load_scene(str(sc / "town.obj")).objects} >= {"road", "water"}


# -- H1, H2, A4: YAML bombs, backtracking, duplicate keys ------------------------------------

BOMB = ("- {scene: [&a [1,1,1,1,1,1,1,1,1], &b [*a,*a,*a,*a,*a,*a,*a,*a,*a], "
        "&c [*b,*b,*b,*b,*b,*b,*b,*b,*b], &d [*c,*c,*c,*c,*c,*c,*c,*c,*c], "
        "&e [*d,*d,*d,*d,*d,*d,*d,*d,*d], &f [*e,*e,*e,*e,*e,*e,*e,*e,*e], "
        "&g [*f,*f,*f,*f,*f,*f,*f,*f,*f]], weight: 1}\n")


@pytest.mark.timeout(60)
def test_h1_scene_mix_alias_bomb_and_deep_nesting(capsys, tmp_path):
    (tmp_path / "bomb.yaml").write_text(BOMB)
    assert len(BOMB) < 400
    t = time.monotonic()
    err = one_line(*run(capsys, "export", "--scene-mix", tmp_path / "bomb.yaml", "--out", tmp_path / "ds"))
    assert "--scene-mix" in err and "expand" in err and time.monotonic() - t < 20
    (tmp_path / "deep.yaml").write_text("- scene: " + "[" * 5000 + "]" * 5000 + "\n  weight: 1\n")
    err = one_line(*run(capsys, "export", "--scene-mix", tmp_path / "deep.yaml", "--out", tmp_path / "ds"))
    assert "nesting" in err and "RecursionError" not in err
    assert not (tmp_path / "ds").exists()


@pytest.mark.timeout(60)
def test_h2_group_regex_cannot_backtrack(capsys, tmp_path):
    name = "a" * 40 + "!"
    gt = make_dota(tmp_path / "G", 1, name)
    (tmp_path / "P").mkdir()
    (tmp_path / "P" / "Task1_small-vehicle.txt").write_text(f"{name}000 0.9 1 1 5 1 5 5 1 5\n")
    t = time.monotonic()
    code, err = run(capsys, "eval", "--gt", gt, "--pred", tmp_path / "P",
                    "--group", "(a+)+$", "--out", tmp_path / "ev")
    assert code == 0, err
    assert time.monotonic() - t < 30  # Python's re: 2**40 steps
    # T2: a repetition count Python's re overflows on, one line
    err = one_line(*run(capsys, "eval", "--gt", gt, "--pred", tmp_path / "P",
                        "--group", "a{99999999999}", "--out", tmp_path / "ev2"))
    assert "--group" in err and "at most 1000" in err and not (tmp_path / "ev2").exists()


def test_h2_sim2real_group_checked_with_re2():
    from aerial_synth.errors import EvaluationError
    from aerial_synth.evaluate.scoring import ScoringOptions, image_groups

    with pytest.raises(EvaluationError, match="no back-references"):
        ScoringOptions(group=r"(a)\1")

    class G:
        name = "a" * 5000 + "!"
        extra: dict = {}

    t = time.monotonic()
    assert image_groups([G()], "(a+)+$") == ["(other)"]
    assert time.monotonic() - t < 5


def test_a4_duplicate_keys_refused_in_every_yaml(capsys, tmp_path):
    (tmp_path / "mix.yaml").write_text("- scene: city_park\n  weight: 1\n  weight: 3\n")
    err = one_line(*run(capsys, "export", "--scene-mix", tmp_path / "mix.yaml", "--out", tmp_path / "ds"))
    assert "'weight' twice" in err and "lines 2 and 3" in err
    (tmp_path / "sc.yaml").write_text("generator: grid\nseed: 1\nseed: 2\n")
    err = one_line(*run(capsys, "scene", "show", tmp_path / "sc.yaml", "--out", tmp_path / "m.png"))
    assert "'seed' twice" in err
    (tmp_path / "names.yaml").write_text("names:\n  0: car\n  0: bus\n")
    from aerial_synth.errors import EvaluationError
    from aerial_synth.evaluate.labels import parse_names

    with pytest.raises(EvaluationError, match="twice"):
        parse_names(str(tmp_path / "names.yaml"))
    # a merge key may be overridden, as YAML intends
    from aerial_synth.safe_input import load_yaml

    assert load_yaml("a: &x {k: 1}\nb:\n  <<: *x\n  k: 2\n", "t") == {"a": {"k": 1}, "b": {"k": 2}}


# -- C1, C2, T1, A3: sizes checked before anything is allocated -------------------------------

GB4 = 4 << 30


def _limited(limit=GB4):
    def pre():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    return pre


@pytest.mark.timeout(120)
def test_c1_t1_huge_label_gsd_is_refused_before_memory(tmp_path):
    make_dota(tmp_path / "R", 1, "r", size=(400, 300), gsd=1e300)
    make_dota(tmp_path / "S", 2, "s")
    for argv in (["mix", "--real", tmp_path / "R", "--synthetic", tmp_path / "S", "--real-fraction",
                  "0.5", "--gsd", "0.12", "--tile", "64", "--overlap", "16", "--out", tmp_path / "mx"],
                 ["stats", tmp_path / "R", "--out", tmp_path / "st"]):
        r = cli(*argv, preexec_fn=_limited(), timeout=100)
        err = r.stderr.decode()
        assert r.returncode == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert "expected gsd in 0.0001..1000 metres per pixel" in err
    assert not (tmp_path / "mx").exists() and not (tmp_path / "st").exists()


def test_c1_rescaled_image_and_tiles_bounded(tmp_path):
    from aerial_synth.errors import EvaluationError
    from aerial_synth.evaluate.tiling import (
        MAX_TILES_PER_IMAGE,
        check_scaled_plan,
        tile_count,
        tile_origins,
    )

    with pytest.raises(EvaluationError, match="OpenCV's limit"):
        check_scaled_plan("x.png", 400, 300, 1e7, 64, 16)  # gsd 1000 -> 1e-4
    with pytest.raises(EvaluationError, match=f"at most {MAX_TILES_PER_IMAGE:,}"):
        check_scaled_plan("x.png", 30000, 30000, 1.0, 2, 1)
    assert check_scaled_plan("x.png", 400, 300, 0.5, 64, 16) == (200, 150)
    for size, tile, ov in ((1, 64, 16), (64, 64, 0), (65, 64, 16), (1000, 100, 30)):
        assert tile_count(size, tile, ov) == len(tile_origins(size, tile, ov))
    assert tile_origins(100, 40, 10) == [0, 30, 60]


def test_t1_mix_target_gsd_bounded(capsys, tmp_path):
    make_dota(tmp_path / "R", 1, "r", size=(400, 300))
    make_dota(tmp_path / "S", 2, "s")
    err = one_line(*run(capsys, "mix", "--real", tmp_path / "R", "--synthetic", tmp_path / "S",
                        "--gsd", "1e-9", "--out", tmp_path / "mx"))
    assert "--gsd" in err and ">= 0.0001" in err
    # the largest GSD a label may give, rescaled to the smallest target: refused by size
    make_dota(tmp_path / "R2", 1, "r", size=(400, 300), gsd=1000)
    err = one_line(*run(capsys, "mix", "--real", tmp_path / "R2", "--synthetic", tmp_path / "S", "--real-images", "1",
                        "--gsd", "1e-4", "--out", tmp_path / "mx"))
    assert "OpenCV's limit" in err and not (tmp_path / "mx").exists()


@pytest.mark.timeout(120)
def test_c2_contact_sheet_memory_checked_first(tmp_path):
    from aerial_synth.errors import ConfigError
    from aerial_synth.vehicles.preview import check_sheet_memory

    with pytest.raises(ConfigError, match=r"needs about 43\.\d GB of memory, 8\.0 GB are available"):
        check_sheet_memory(190.3, 95.06, 0.01, available=8_000_000_000)
    check_sheet_memory(190.3, 95.06, 0.04, available=8_000_000_000)  # 2.7 GB: fits
    r = cli("assets", "preview", "--out", tmp_path / "a.png", "--gsd", "0.005",
            preexec_fn=_limited(), timeout=100)
    err = r.stderr.decode()
    assert r.returncode == 2 and err.count("\n") == 1 and "ulimit -v" in err, err
    assert not (tmp_path / "a.png").exists()


def test_a3_altitude_and_gsd_bounds(capsys, tmp_path):
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.config import ExportConfig
    from aerial_synth.errors import CameraError, ExportError

    for argv in (["--altitude", "1e-9:1"], ["--altitude", "0.001"], ["--gsd", "1e-9"]):
        err = one_line(*run(capsys, "export", *argv, "--images", "1", "--out", tmp_path / "ds"))
        assert argv[0] in err and ">=" in err
    with pytest.raises(CameraError, match="altitude_m"):
        CameraConfig(altitude_m=9.0)
    with pytest.raises(CameraError, match="focal_px: at altitude 60 m it gives a nadir GSD"):
        CameraConfig(focal_px=1e6)  # 0.06 mm per pixel
    with pytest.raises(ExportError, match="--gsd: the range's lens"):
        ExportConfig(gsd_range=(0.005, 1.0))  # the lens puts 0.005 m/px at 4 m altitude
    assert ExportConfig(gsd_range=(0.05, 0.3)).camera_config().altitude_m == pytest.approx(0.3 * 60 / (0.05 * 0.3) ** 0.5)
    assert not (tmp_path / "ds").exists()


# -- H3, T5: signals ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def town_osm(tmp_path_factory):
    from tests.scene.osm_town import make_town

    return make_town().write(tmp_path_factory.mktemp("osm3") / "town.osm")


def _unblocked():
    """A child inherits its parent's signal mask and ignored signals: a test process that
    has SIGTERM/SIGINT blocked at that moment (multiprocessing blocks them while it starts
    its helpers) or SIGINT ignored (a pool's initializer run in-process) would hand its
    children what no interactive shell gives. Reset both, as a terminal would."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM, signal.SIGINT, signal.SIGHUP})
    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(s, signal.SIG_DFL)


def _signalled(argv, sig, delay, cwd):
    p = subprocess.Popen([sys.executable, "-m", "aerial_synth.cli", *map(str, argv)], cwd=cwd,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=_unblocked,
                         env=dict(os.environ, PYTHONPATH=str(REPO)))
    time.sleep(delay)
    p.send_signal(sig)
    err = p.communicate(timeout=60)[1].decode()
    return p.returncode, err


SWALLOWING_RUN = """
import os, signal, sys, time
from aerial_synth import cli
from aerial_synth.scene import commands

build = commands.load_osm_scene

def swallowing(*a, **k):
    try:  # trimesh wraps its optional imports so: the signal arrives inside, and is eaten
        os.kill(os.getpid(), getattr(signal, sys.argv[1]))
        time.sleep(0.5)
    except BaseException:
        pass
    time.sleep(0.6)  # the library's own work after the swallowed signal (a reminder falls in it)
    return build(*a, **k)

commands.load_osm_scene = swallowing
sys.exit(cli.console_main(sys.argv[2:]))
"""


@pytest.mark.timeout(180)
@pytest.mark.parametrize("sig,status,word", [(signal.SIGTERM, 143, "terminated (SIGTERM)"),
                                             (signal.SIGINT, 130, "interrupted")])
def test_h3_from_osm_stops_on_a_signal_a_library_swallowed(tmp_path, town_osm, sig, status, word):
    # trimesh catches BaseException around its optional imports, ~2 s into the build: the
    # signal it swallowed is raised again until the CLI catches it; nothing is written
    out = tmp_path / "o.glb"
    r = subprocess.run([sys.executable, "-c", SWALLOWING_RUN, sig.name, "scene", "from-osm", str(town_osm),
                        "--out", str(out), "--no-cache"], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, PYTHONPATH=str(REPO)), cwd=tmp_path, preexec_fn=_unblocked)
    # after Ctrl-C, CPython may itself end the process by SIGINT once main() returned 130
    assert r.returncode in (status, -sig if sig == signal.SIGINT else status), (r.returncode, r.stderr)
    assert r.stderr.strip().splitlines() == [f"aerial-synth: {word}"], r.stderr
    assert r.stdout == "" and sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.timeout(180)
def test_h3_from_osm_stops_on_sigterm_during_its_build(tmp_path, town_osm):
    code, err = _signalled(["scene", "from-osm", town_osm, "--out", tmp_path / "o.glb", "--no-cache"],
                           signal.SIGTERM, 1.0, tmp_path)
    if code == 0:  # a fast machine finished first: nothing to see
        return
    assert code in (143, -signal.SIGTERM), (code, err)  # -15: still starting, no handler yet
    assert err.strip().splitlines() == (["aerial-synth: terminated (SIGTERM)"] if code == 143 else []), err
    assert not (tmp_path / "o.glb").exists()


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_t5_signal_during_start_up_is_one_line(tmp_path, sig):
    for delay in (0.15, 0.4, 0.8):
        code, err = _signalled(["stats", tmp_path / "nosuch", "--out", tmp_path / "st"], sig, delay,
                               tmp_path)
        if code == 2:  # the run was over before the signal: nothing to see
            continue
        if code == -sig:  # before the CLI's handlers (interpreter start) or after them (the
            # run was over): killed by the signal's default action, with no traceback
            assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
            continue
        assert code == 128 + sig, err
        assert err.strip().splitlines() == [f"aerial-synth: terminated ({sig.name})"], err


# -- K1: every writing command takes the --out lock --------------------------------------------


@pytest.mark.parametrize("argv", [
    ["place", "--scene", "city_park", "--out", "{out}"],
    ["place-tiled", "--scene", "city_park", "--out", "{out}"],
    ["render", "--scene", "city_park", "--out", "{out}"],
    ["scene", "export", "city_park", "--out", "{out}.glb"],
    ["scene", "show", "city_park", "--out", "{out}.png"],
    ["assets", "preview", "--out", "{out}.png"],
    ["sim2real", "--synthetic", "{tmp}", "--real", "{tmp}", "--out", "{out}"],
], ids=lambda a: " ".join(a[:2]))
def test_k1_a_second_writer_is_refused_by_every_command(capsys, tmp_path, argv):
    from aerial_synth.out_guard import out_lock

    out = tmp_path / "D"
    argv = [a.format(out=out, tmp=tmp_path) for a in argv]
    target = argv[argv.index("--out") + 1]
    with out_lock(target, "another run"):  # a second process would hold it the same way
        err = one_line(*run(capsys, *argv))
    assert "another aerial-synth run is writing it right now" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_k1_the_command_s_own_lock_nests_in_the_cli_s(capsys, tmp_path):
    make_dota(tmp_path / "R", 1, "r")
    code, err = run(capsys, "stats", tmp_path / "R", "--out", tmp_path / "st")
    assert code == 0, err  # stats takes out_lock again inside: a no-op, not a refusal
    assert (tmp_path / "st" / "stats.json").is_file()
    assert not any(p.name.endswith(".aerial-synth-lock") for p in tmp_path.iterdir())


# -- T3: link loops ------------------------------------------------------------------------------


def test_t3_symlink_loop_is_one_line(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    os.symlink("l2", "l1")
    os.symlink("l1", "l2")
    make_dota(tmp_path / "R", 1, "r")
    for argv in (["stats", "l1/x", "--out", "st"], ["eval", "--gt", "l1/x", "--pred", "l1", "--out", "ev"],
                 ["stats", "R", "--compare", "l1", "--out", "st"],
                 ["assets", "list", "--catalog", "l1/c.yaml"]):
        err = one_line(*run(capsys, *argv))
        assert "RuntimeError" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["R", "l1", "l2"]


# -- W1, W2: nothing half-written -----------------------------------------------------------------


def test_w1_eval_report_failing_late_leaves_no_folder(capsys, tmp_path):
    gt = make_dota(tmp_path / "G", 2, "g")
    (tmp_path / "P").mkdir()
    (tmp_path / "P" / "Task1_small-vehicle.txt").write_text("g000 0.9 1 1 5 1 5 5 1 5\n")
    code, err = run(capsys, "eval", "--gt", gt, "--pred", tmp_path / "P", "--merge-classes", "v" * 300,
                    "--out", tmp_path / "ev")
    one_line(code, err)
    assert "File name too long" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["G", "P"]  # no ev/, no temporary


def test_w1_staged_dir_keeps_out_as_it_was(tmp_path):
    from aerial_synth.out_guard import staged_dir

    out = tmp_path / "rep"
    out.mkdir()
    (out / "mine.txt").write_text("user")
    (out / "a.txt").write_text("old")
    with pytest.raises(OSError):
        with staged_dir(out) as b:
            (b / "a.txt").write_text("new")
            raise OSError(28, "No space left on device")
    assert tree_bytes(out) == {"mine.txt": b"user", "a.txt": b"old"}
    with staged_dir(out) as b:
        (b / "a.txt").write_text("new")
        (b / "sub").mkdir()
        (b / "sub" / "c.txt").write_text("c")
    assert tree_bytes(out) == {"mine.txt": b"user", "a.txt": b"new", "sub/c.txt": b"c"}
    with staged_dir(tmp_path / "new" / "deep") as b:
        (b / "x").write_text("x")
    assert (tmp_path / "new" / "deep" / "x").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new", "rep"]


@pytest.fixture
def full_disk(tmp_path):
    """A 1 MB tmpfs (needs root, as in the project's containers and CI jobs run as root)."""
    d = tmp_path / "full"
    d.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(d)],
                                           capture_output=True).returncode != 0:
        pytest.skip("mounting a small tmpfs needs root; the in-process ENOSPC tests cover the logic")
    yield d
    subprocess.run(["umount", str(d)], capture_output=True)


@pytest.mark.timeout(300)
def test_w1_w2_full_disk(tmp_path, full_disk):
    make_dota(tmp_path / "R", 6, "r", size=(800, 600))
    r = cli("stats", tmp_path / "R", "--out", full_disk / "st", timeout=200)
    err = r.stderr.decode()
    assert r.returncode == 2 and err.count("\n") == 1 and "No space left" in err, err
    assert os.listdir(full_disk) == []  # no st/, no temporary
    r = cli("export", "--scene", "city_park", "--images", "40", "--size", "256", "--simple-vehicles",
            "--out", full_disk / "ds", "--no-progress", timeout=280)
    err = r.stderr.decode()
    assert r.returncode == 2 and err.count("\n") == 1 and "No space left" in err, err
    left = os.listdir(full_disk)
    if left:  # kept for --resume: the line says so and names it
        assert left == [".ds.aerial-synth-partial"] and "--resume" in err and left[0] in err, (left, err)


def test_w2_export_full_disk_names_the_partial(tmp_path, monkeypatch, capsys):
    import errno

    from aerial_synth.dataset import worker

    calls = []
    real = worker._write_files

    def failing(cfg, out, record, data):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, "No space left on device", str(out / "x.png"))
        return real(cfg, out, record, data)

    monkeypatch.setattr(worker, "_write_files", failing)
    code, err = run(capsys, "export", "--scene", "city_park", "--images", "3", "--size", "96",
                    "--simple-vehicles", "--no-progress", "--out", tmp_path / "ds")
    one_line(code, err)
    assert "No space left on device" in err and ".ds.aerial-synth-partial" in err and "--resume" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == [".ds.aerial-synth-partial"]


# -- A1, A2: the Python API refuses what the CLI refuses -----------------------------------------


@pytest.mark.parametrize("kw,field", [
    (dict(epochs=float("nan"), minutes=None), "--epochs"), (dict(epochs=float("inf"), minutes=None), "--epochs"),
    (dict(epochs=1.5, minutes=None), "--epochs"), (dict(seed=float("nan")), "--seed"),
    (dict(batch=float("nan")), "--batch"), (dict(ignore_border={None: -5}), "--ignore-border *"),
    (dict(ignore_border={"car": float("nan")}), "--ignore-border car"), (dict(arms=()), "--synthetic"),
    (dict(minutes="soon"), "--minutes"), (dict(imgsz="big"), "--imgsz"), (dict(conf="high"), "--conf"),
    (dict(minutes=float("nan")), "--minutes"), (dict(gsd=1e300), "--gsd"), (dict(group="(a)\\1"), "--group"),
])
def test_a1_sim2real_config_checks_every_field(tmp_path, kw, field):
    from aerial_synth.sim2real.config import Arm, Sim2RealConfig, Sim2RealError

    base = dict(arms=(Arm("syn", (tmp_path,)),), real=tmp_path, out=tmp_path / "o")
    with pytest.raises(Sim2RealError) as e:
        Sim2RealConfig(**{**base, **kw})
    assert str(e.value).startswith(field + ":") and "\n" not in str(e.value)
    ok = Sim2RealConfig(**base, conf="0.01", imgsz=640.0)
    assert ok.conf == 0.01 and ok.imgsz == 640 and isinstance(ok.imgsz, int)


def test_a2_public_api_refuses_nan_and_wrong_types():
    from aerial_synth.camera import CameraConfig, grid_poses
    from aerial_synth.errors import AssetError, CameraError, SceneError
    from aerial_synth.scene.mapview import render_map
    from aerial_synth.vehicles.catalog import load_catalog
    from aerial_synth.vehicles.meshes import build_mesh

    cat = load_catalog(None)
    mesh = build_mesh(cat.models[0], cat.colors[0])
    cases = [
        (lambda: grid_poses(CameraConfig(), [[0, 0], [100, 100]], ground_z=float("nan")), CameraError, "ground_z"),
        (lambda: grid_poses(CameraConfig(), [[0, 0], [float("inf"), 100]]), CameraError, "bounds"),
        (lambda: grid_poses(CameraConfig(), [[0, 0], [1e300, 1e300]]), CameraError, "bounds"),
        (lambda: grid_poses(CameraConfig(), "nonsense"), CameraError, "bounds"),
        (lambda: mesh.to_world(float("nan"), 0.0, 0.0, 0.0), AssetError, "x_m"),
        (lambda: mesh.to_world(0.0, 0.0, 0.0, float("inf")), AssetError, "heading_rad"),
        (lambda: cat.sample(np.random.default_rng(0), -1), AssetError, "catalog sample n"),
        (lambda: render_map(None), SceneError, "expected a Scene"),
    ]
    for f, err, field in cases:
        with pytest.raises(err, match=field):
            f()
    poses = grid_poses(CameraConfig(), [[0, 0], [300, 300]], ground_z=2.0)
    assert len(poses) == 9 and all(np.isfinite(c.cam_to_world).all() for c in poses)
    v, _ = mesh.to_world(1.0, 2.0, 0.0, 0.5)
    assert np.isfinite(v).all()


def test_h3_reminders_leave_a_caller_s_alarm_alone(capsys):
    """The re-raising timer is armed only while a signal is pending, and the SIGALRM handler
    and timer in place before (pytest-timeout's, say) come back after."""
    from aerial_synth import cli

    def mine(signum, frame):
        pass

    old = signal.signal(signal.SIGALRM, mine)
    signal.setitimer(signal.ITIMER_REAL, 500.0)
    try:
        assert cli.main(["assets", "list"]) == 0
        assert signal.getsignal(signal.SIGALRM) is mine and signal.getitimer(signal.ITIMER_REAL)[0] > 400
        # a pending termination: raised again until caught, then everything is restored
        with cli._terminate_as_interrupt():
            with pytest.raises(cli.Terminated):
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(1)
            assert cli._PENDING == [signal.SIGTERM]
            with pytest.raises(cli.Terminated):  # swallowed once: it comes back
                time.sleep(2)
            cli._disarm()
        assert signal.getsignal(signal.SIGALRM) is mine and signal.getitimer(signal.ITIMER_REAL)[0] > 400
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    capsys.readouterr()
