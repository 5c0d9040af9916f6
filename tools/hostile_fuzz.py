"""Fuzz the whole ``aerial-synth`` CLI as a hostile user would (issue 37).

Cases come from the argparse definitions of every subcommand (:func:`command_specs`): each
starts from a cheap valid command line (:data:`BASE`) and replaces one to three of its
options (or positionals) with values drawn by hypothesis:

- numbers: 0, -1, NaN, +-inf, +-1e-300, +-1e300 and the edges of each option's accepted
  range (read from its ``arg_int`` / ``arg_float`` converter: lo, hi and just outside);
- strings: ``''``, ``.``, ``/``, undecodable bytes, 300 characters;
- paths: a FIFO, a device, a folder, a loop of links, a folder whose label file links out of
  it (to a secret), a file on a full disk (a 1 MB tmpfs when run as root), a missing path.

Each case runs in a child process (forked from a server that has imported the CLI and its
heavy libraries once, with one BLAS thread) under a 4 GB address-space limit and a time
limit, in a folder of its own holding the fixtures. It passes when:

- the exit status is 0, or 2 with exactly one line on stderr (warnings aside), or, when the
  time limit sent SIGTERM, 143 with the one line ``aerial-synth: terminated (SIGTERM)``;
- no traceback is printed and the secret behind the escaping link is never shown;
- nothing in the case folder changed except ``--out`` (with its lock and temporaries), and
  the full disk holds nothing afterwards but a partial export the message names.

    python tools/hostile_fuzz.py --cases 2000 --jobs 2          # make test-hostile
    python tools/hostile_fuzz.py --cases 40 --seed 1 --report r.json

Prints the number of cases, the failures (command line, status, stderr) and the run time;
exits 1 when a case failed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

AS_LIMIT = 4 << 30
SECRET = "s3cr3t-TOKEN-37"
NUMBERS = ["0", "-1", "nan", "inf", "-inf", "1e-300", "-1e-300", "1e300", "-1e300"]
STRINGS = ["", ".", "/", "\udcff\udcfeab", "v" * 300]
BAD_PATHS = ["@fifo", "@dev", "@dir", "@loop", "@escape", "@full", "@missing"]
RANGES = ["1:2", "0:1", "nan:1", "1e-300:1e300", "2:1", "1:1", "a:b", "1:2:3"]

#: A cheap valid command line per command: {key: value}, a key being an option string or
#: ``#<dest>`` for a positional; ``@name`` values are fixtures of the case folder.
BASE: dict[tuple[str, ...], dict[str, str | None]] = {
    ("scene", "list"): {},
    ("scene", "show"): {"#scene": "@mesh", "--out": "m.png", "--m-per-px": "1"},
    ("scene", "export"): {"#scene": "@mesh", "--out": "s.glb"},
    ("scene", "from-osm"): {"#file": "@osm", "--out": "o.glb", "--no-cache": None},
    ("assets", "list"): {},
    ("assets", "preview"): {"--out": "a.png", "--gsd": "0.5"},
    ("place",): {"--scene": "@mesh", "--vehicles": "5", "--no-png": None, "--out": "pl"},
    ("place-tiled",): {"--scene": "@mesh", "--vehicles": "5", "--tile-m": "40", "--out": "pt"},
    ("render",): {"--scene": "@mesh", "--vehicles": "3", "--images": "1", "--size": "64", "--out": "rd"},
    ("export",): {"--scene": "@mesh", "--images": "1", "--size": "64", "--simple-vehicles": None,
                  "--no-progress": None, "--out": "ds"},
    ("show",): {"#dir": "@dota", "--out": "sh"},
    ("eval",): {"--gt": "@dota", "--pred": "@pred", "--out": "ev"},
    ("mix",): {"--real": "@dota", "--synthetic": "@dota2", "--real-images": "1", "--out": "mx"},
    ("stats",): {"#dir": "@dota", "--out": "st"},
    ("sim2real",): {"--synthetic": "@dota2", "--real": "@dota", "--out": "s2"},
    ("sim2real", "score"): {"--weights": "@mesh", "--real": "@dota", "--out": "sc"},
}


@dataclass
class Option:
    key: str  # option string, or #dest for a positional
    kind: str  # flag, integer, number, range, choice, path, text
    choices: tuple = ()
    edges: tuple = ()


@dataclass
class Spec:
    command: tuple[str, ...]
    options: list[Option] = field(default_factory=list)
    out_default: str | None = None  # where the command writes without --out


def _edges(conv) -> tuple:
    """lo, hi and values just outside, from an arg_int / arg_float converter's closure."""
    try:
        cells = dict(zip(conv.__code__.co_freevars, (c.cell_contents for c in conv.__closure__ or ())))
    except (AttributeError, ValueError):
        return ()
    out = []
    integer = getattr(conv, "__name__", "") == "integer"
    for k, step in (("lo", -1), ("hi", 1)):
        v = cells.get(k)
        if isinstance(v, (int, float)) and v == v:
            out.append(repr(int(v)) if integer else repr(float(v)))
            outside = v + step if integer else (v - abs(v) * 1e-9 - 1e-12 if step < 0 else v + abs(v) * 1e-9 + 1e-12)
            out.append(repr(int(outside)) if integer else repr(float(outside)))
    return tuple(out)


_PATHY = ("FILE", "DIR", "PNG", "YAML", "PATH", "GLB", "OSM")


def command_specs(parser=None) -> dict[tuple[str, ...], Spec]:
    """Every leaf command of the CLI with the kinds of its options, from argparse."""
    from aerial_synth.cli import build_parser
    from aerial_synth.out_guard import INPUT_OPTIONS

    parser = parser or build_parser()
    specs: dict[tuple[str, ...], Spec] = {}

    def walk(p, path):
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if subs:
            for name, sp in subs[0].choices.items():
                walk(sp, path + (name,))
            if subs[0].required or not path:
                return  # a command that only groups others (`scene`); else also runnable (`sim2real`)
        spec = Spec(path)
        for a in p._actions:
            if isinstance(a, (argparse._HelpAction, argparse._VersionAction,
                              argparse._SubParsersAction)):
                continue
            key = a.option_strings[-1] if a.option_strings else f"#{a.dest}"
            if a.dest == "out" and isinstance(a.default, str):
                spec.out_default = a.default
            tname = getattr(a.type, "__name__", "")
            metavar = str(a.metavar or "")
            if a.nargs == 0:
                kind = "flag"
            elif tname in ("integer", "number"):
                kind = tname
            elif tname == "range":
                kind = "range"
            elif a.choices or tname == "choice":
                kind = "choice"
            elif a.dest in INPUT_OPTIONS or a.dest == "out" or any(w in metavar.upper() for w in _PATHY):
                kind = "path"
            else:
                kind = "text"
            choices = tuple(a.choices or ())
            spec.options.append(Option(key, kind, choices, _edges(a.type) if kind in ("integer", "number") else ()))
        specs[path] = spec

    walk(parser, ())
    return specs


def case_strategy(specs):
    """A hypothesis strategy of cases: (command, {key: value})."""
    from hypothesis import strategies as st

    commands = sorted(specs)

    def values(opt: Option):
        if opt.kind == "flag":
            return st.just(None)
        if opt.kind in ("integer", "number"):
            return st.sampled_from(NUMBERS + list(opt.edges) + STRINGS[:2])
        if opt.kind == "range":
            return st.sampled_from(NUMBERS + RANGES + STRINGS[:2])
        if opt.kind == "choice":
            return st.sampled_from([str(c) for c in opt.choices] + STRINGS)
        if opt.kind == "path":
            return st.sampled_from(BAD_PATHS + STRINGS + ["@mesh", "@dota", "@dota2", "@osm", "@secret_link"])
        return st.sampled_from(STRINGS + NUMBERS[:3] + ["a=b", "x:1", "@escape"])

    @st.composite
    def case(draw):
        cmd = draw(st.sampled_from(commands))
        spec = specs[cmd]
        argv = dict(BASE.get(cmd, {}))
        if spec.options:
            picks = draw(st.lists(st.sampled_from(spec.options), min_size=1, max_size=3,
                                  unique_by=lambda o: o.key))
            for opt in picks:
                argv[opt.key] = draw(values(opt))
        if argv and draw(st.integers(0, 19)) == 0:  # now and then, a required value missing
            argv.pop(draw(st.sampled_from(sorted(argv))))
        return cmd, argv

    return case()


def draw_cases(n: int, seed: int, specs=None) -> list[tuple[tuple[str, ...], dict]]:
    """``n`` distinct cases, the same for the same seed."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    specs = specs or command_specs()
    out: dict[str, tuple] = {}
    sink: list = []
    for round_ in range(20):
        if len(out) >= n:
            break
        sink.clear()

        @hseed(seed * 1000 + round_)
        @settings(max_examples=n, database=None, phases=[Phase.generate], deadline=None,
                  suppress_health_check=list(HealthCheck))
        @given(case_strategy(specs))
        def collect(c):
            sink.append(c)

        collect()
        for cmd, argv in sink:
            out.setdefault(json.dumps([cmd, argv], sort_keys=True), (cmd, argv))
    return list(out.values())[:n]


# -- fixtures ----------------------------------------------------------------------------------


def make_template(root: Path) -> Path:
    """The fixtures every case folder starts from."""
    from tests.evaluate.conftest import make_dota
    from tests.helpers import write_crossing_obj
    from tests.scene.osm_town import make_town

    t = root / "template"
    t.mkdir(parents=True)
    write_crossing_obj(t / "mesh.obj", 40)
    make_dota(t / "R", 2, "r", size=(200, 160))
    make_dota(t / "S", 2, "s", size=(200, 160))
    (t / "P").mkdir()
    (t / "P" / "Task1_small-vehicle.txt").write_text("r000 0.9 1 1 5 1 5 5 1 5\n")
    make_town().write(t / "town.osm")
    (t / "secret.txt").write_text(SECRET + "\n")
    make_dota(t / "E", 1, "e")
    lab = t / "E" / "labelTxt" / "e000.txt"
    lab.unlink()
    lab.symlink_to("../../secret.txt")  # a label file that links out of its folder
    (t / "D").mkdir()
    (t / "loop").mkdir()
    os.symlink("l2", t / "loop" / "l1")
    os.symlink("l1", t / "loop" / "l2")
    os.symlink("secret.txt", t / "link.yaml")
    return t


FIXTURES = {"@mesh": "mesh.obj", "@dota": "R", "@dota2": "S", "@pred": "P", "@osm": "town.osm",
            "@dir": "D", "@loop": "loop/l1/x", "@escape": "E", "@missing": "nosuch/x",
            "@fifo": "fifo", "@secret_link": "link.yaml", "@dev": "/dev/zero"}


def _resolve(value: str | None, full: Path | None, case_id: int) -> str | None:
    if value is None or not value.startswith("@"):
        return value
    if value == "@full":
        return str(full / f"c{case_id}") if full is not None else "/dev/full"
    return FIXTURES[value]


def argv_of(cmd, argv: dict, full: Path | None, case_id: int) -> list[str]:
    out = list(cmd)
    for k, v in argv.items():
        if k.startswith("#"):
            if v is not None:
                out.append(_resolve(v, full, case_id))
    for k, v in argv.items():
        if not k.startswith("#"):
            out.append(k)
            if v is not None:
                out.append(_resolve(v, full, case_id))
    return out


# -- the run -----------------------------------------------------------------------------------


def _snapshot(root: Path, skip: set[str]) -> dict[str, tuple]:
    snap = {}
    for dirpath, dirnames, filenames in os.walk(root):
        rel_dir = os.path.relpath(dirpath, root)
        dirnames[:] = [d for d in dirnames if os.path.normpath(os.path.join(rel_dir, d)) not in skip]
        for name in filenames + [d for d in dirnames if os.path.islink(os.path.join(dirpath, d))]:
            rel = os.path.normpath(os.path.join(rel_dir, name))
            if rel in skip:
                continue
            p = os.path.join(dirpath, name)
            st = os.lstat(p)
            if os.path.islink(p):
                snap[rel] = ("link", os.readlink(p))
            elif os.path.isfile(p):
                with open(p, "rb") as fh:
                    snap[rel] = ("file", hashlib.sha1(fh.read()).hexdigest())
            else:
                snap[rel] = ("other", st.st_mode)
    return snap


def _out_names(argv: list[str]) -> str | None:
    if "--out" in argv:
        i = argv.index("--out")
        return argv[i + 1] if i + 1 < len(argv) else None
    return None


def _allowed(rel: str, out: str | None) -> bool:
    """Paths a case may create or change: --out, below it, its lock and temporaries."""
    if rel.split(os.sep)[0] in (".cache", ".xdg", ".tmp", ".home"):
        return True
    if not out:
        return False
    o = os.path.normpath(out)
    if o in (".", "") or o.startswith(".."):
        return False
    head, name = os.path.split(o)
    if rel == o or rel.startswith(o + os.sep):
        return True
    sib_dir, sib = os.path.split(rel)
    return sib_dir == head and sib.startswith(f".{name}.")


def _child(argv: list[str], case_dir: Path, log: Path, err: Path) -> None:  # pragma: no cover - forked
    try:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (AS_LIMIT, AS_LIMIT))
        os.chdir(case_dir)
        for k, d in (("AERIAL_SYNTH_CACHE", ".cache"), ("XDG_CACHE_HOME", ".xdg"), ("TMPDIR", ".tmp"),
                     ("HOME", ".home")):
            os.environ[k] = str(case_dir / d)
        tempfile.tempdir = None
        fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        fd2 = os.open(err, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        null = os.open(os.devnull, os.O_RDWR)
        os.dup2(null, 0)
        os.dup2(fd, 1)
        os.dup2(fd2, 2)
        sys.stdout = os.fdopen(1, "w", closefd=False)
        sys.stderr = os.fdopen(2, "w", closefd=False)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        from aerial_synth.cli import console_main

        code = console_main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:
        import traceback

        traceback.print_exc()
        code = 1
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(int(code or 0) & 0xFF)


@dataclass
class Result:
    case: int
    argv: list[str]
    status: int
    seconds: float
    stderr: str
    problems: list[str]
    timed_out: bool = False


def _judge(r: Result, before, after, out, full: Path | None, log_text: str) -> None:
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    errors = [ln for ln in lines if not ln.startswith("aerial-synth: warning:")]
    if "Traceback" in log_text:
        r.problems.append("traceback")
    if SECRET in log_text:
        r.problems.append("the secret behind a link was shown")
    if r.timed_out:
        if r.status != 143 or errors[-1:] != ["aerial-synth: terminated (SIGTERM)"]:
            r.problems.append(f"did not stop on SIGTERM at the time limit (status {r.status})")
    elif r.status == 2:
        if len(errors) != 1:
            r.problems.append(f"exit 2 with {len(errors)} lines on stderr")
    elif r.status != 0:
        r.problems.append(f"exit status {r.status}")
    changed = sorted(k for k in set(before) | set(after)
                     if before.get(k) != after.get(k) and not _allowed(k, out))
    if changed:
        r.problems.append("changed outside --out: " + ", ".join(changed[:5]))
    if full is not None and full.exists():  # this case's entries (cases run side by side)
        left = [p for p in os.listdir(full) if p == f"c{r.case}" or p.startswith(f".c{r.case}.")]
        for p in left:
            if not (p.endswith(".aerial-synth-partial") and p in r.stderr):
                r.problems.append(f"left on the full disk: {p}")
            shutil.rmtree(full / p, ignore_errors=True)


def _mount_full(work: Path) -> Path | None:
    """A 1 MB tmpfs filled to the last few KB (root only), else None."""
    d = work / "full"
    d.mkdir()
    if os.geteuid() != 0:
        return None
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(d)],
                      capture_output=True).returncode != 0:
        return None
    with open(d / "filler", "wb") as fh:
        try:
            fh.write(b"\0" * (1 << 20))
        except OSError:
            pass
    return d


def run_cases(cases, work: Path, jobs: int = 2, timeout: float = 30.0, verbose=False) -> list[Result]:
    """Run ``cases`` (from :func:`draw_cases`) ``jobs`` at a time; every Result."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ["OPENCV_LOG_LEVEL"] = "SILENT"
    # the server imports what most commands import, once (the children inherit it)
    from aerial_synth.cli import build_parser

    build_parser()
    import cv2  # noqa: F401
    import numba  # noqa: F401
    import open3d  # noqa: F401
    import scipy.spatial  # noqa: F401
    import shapely  # noqa: F401
    import trimesh  # noqa: F401

    specs = command_specs()
    template = make_template(work)
    full = _mount_full(work)
    results: list[Result] = []
    running: dict[int, tuple] = {}
    queue = list(enumerate(cases))
    try:
        while queue or running:
            while queue and len(running) < jobs:
                k, (cmd, spec) = queue.pop(0)
                case_dir = work / f"case{k}"
                shutil.copytree(template, case_dir, symlinks=True)
                os.mkfifo(case_dir / "fifo")
                for d in (".cache", ".xdg", ".tmp", ".home"):
                    (case_dir / d).mkdir()
                argv = argv_of(cmd, spec, full, k)
                log, err = work / f"case{k}.out", work / f"case{k}.err"
                skip = {".cache", ".xdg", ".tmp", ".home"}
                before = _snapshot(case_dir, skip)
                pid = os.fork()
                if pid == 0:  # pragma: no cover
                    _child(argv, case_dir, log, err)
                running[pid] = (k, argv, case_dir, (log, err), before, time.monotonic(), False)
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                now = time.monotonic()
                for p, (k, argv, case_dir, log, before, t0, termed) in list(running.items()):
                    if not termed and now - t0 > timeout:
                        os.kill(p, signal.SIGTERM)
                        running[p] = (k, argv, case_dir, log, before, t0, True)
                    elif termed and now - t0 > timeout + 20:
                        os.kill(p, signal.SIGKILL)
                time.sleep(0.02)
                continue
            k, argv, case_dir, log, before, t0, termed = running.pop(pid)
            cmd = cases[k][0]
            code = os.waitstatus_to_exitcode(status)
            out_text, err_text = (p.read_text(errors="replace") if p.exists() else "" for p in log)
            r = Result(k, argv, code, round(time.monotonic() - t0, 2), err_text, [], termed)
            after = _snapshot(case_dir, {".cache", ".xdg", ".tmp", ".home"})
            out = _out_names(argv)
            if out is None and "--out" not in argv:
                out = specs[cmd].out_default  # the command's default output
            _judge(r, before, after, out, full, out_text + err_text)
            results.append(r)
            if verbose:
                print(f"{k:5d} {r.status:4d} {r.seconds:6.1f}s {'FAIL ' + '; '.join(r.problems) if r.problems else 'ok'}"
                      f"  {' '.join(argv)[:150]!r}", flush=True)
            shutil.rmtree(case_dir, ignore_errors=True)
            for p in log:
                p.unlink(missing_ok=True)
    finally:
        for p in running:
            try:
                os.kill(p, signal.SIGKILL)
            except OSError:
                pass
        if full is not None:
            subprocess.run(["umount", str(full)], capture_output=True)
    return sorted(results, key=lambda r: r.case)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=2000)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=30.0, help="seconds per case before SIGTERM")
    ap.add_argument("--report", type=Path, default=None, help="write every result as JSON here")
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args(argv)
    # a SIGTERM to the runner unwinds it (children killed, the tmpfs unmounted, folders removed)
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    t0 = time.monotonic()
    cases = draw_cases(a.cases, a.seed)
    with tempfile.TemporaryDirectory(prefix="aerial-synth-fuzz-") as tmp:
        results = run_cases(cases, Path(tmp), a.jobs, a.timeout, a.verbose)
    wall = time.monotonic() - t0
    failed = [r for r in results if r.problems]
    per_cmd: dict[str, int] = {}
    for r in results:
        key = " ".join(x for x in r.argv[:2] if not x.startswith("-"))
        per_cmd[key] = per_cmd.get(key, 0) + 1
    for r in failed:
        print(f"FAIL case {r.case}: {'; '.join(r.problems)}\n  argv: {r.argv!r}\n  status {r.status}, "
              f"stderr: {r.stderr.strip()[-600:]!r}")
    timeouts = sum(r.timed_out for r in results)
    print(f"hostile fuzz: {len(results)} cases, {len(failed)} failures, {timeouts} stopped at the "
          f"time limit, {sum(r.status == 0 for r in results)} succeeded, "
          f"{sum(r.status == 2 for r in results)} refused; {wall:.0f} s")
    if a.report:
        a.report.write_text(json.dumps([r.__dict__ for r in results], indent=1))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
