"""The hostile fuzzer of the whole CLI (tools/hostile_fuzz.py, issue 37): a sample of its
cases runs here (``make test-hostile`` runs >= 2,000), and its oracle is shown to catch each
kind of failure it looks for."""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from tests.helpers import REPO


def _fuzz():
    spec = importlib.util.spec_from_file_location("hostile_fuzz", REPO / "tools" / "hostile_fuzz.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["hostile_fuzz"] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def fuzz():
    return _fuzz()


def test_specs_come_from_every_subcommand(fuzz):
    from aerial_synth.cli import build_parser

    specs = fuzz.command_specs(build_parser())
    assert set(fuzz.BASE) == set(specs)  # every leaf command has a cheap valid start
    kinds = {o.key: o for o in specs[("export",)].options}
    assert kinds["--images"].kind == "integer" and kinds["--images"].edges == ("1", "0", "1000000", "1000001")
    assert kinds["--gsd"].kind == "range" and kinds["--out"].kind == "path"
    assert kinds["--resume"].kind == "flag" and kinds["--format"].kind == "text"
    assert any(o.key == "#dir" and o.kind == "path" for o in specs[("stats",)].options)


def test_cases_are_deterministic_and_varied(fuzz):
    a, b = fuzz.draw_cases(60, seed=3), fuzz.draw_cases(60, seed=3)
    assert a == b and len(a) == 60
    assert len({cmd for cmd, _ in a}) >= 10
    values = {v for _, argv in a for v in argv.values()}
    assert {"nan", "@fifo"} & values and any(v and len(v) == 300 for v in values if isinstance(v, str))


@pytest.mark.timeout(300)
def test_a_sample_of_hostile_cases_passes(fuzz, tmp_path):
    t0 = time.monotonic()
    # in a process of its own, as make test-hostile runs it: the runner forks its cases, and a
    # fork of this pytest process, whose earlier tests started numba's OpenMP threads, aborts
    # in the child ("fork() called from a process already using GNU OpenMP")
    report = tmp_path / "report.json"
    proc = subprocess.run([sys.executable, str(REPO / "tools" / "hostile_fuzz.py"), "--cases", "40",
                           "--seed", "11", "--jobs", "2", "--timeout", "60", "--report", str(report)],
                          capture_output=True, text=True, timeout=280)
    results = json.loads(report.read_text())
    failed = [(r["argv"], r["status"], r["problems"], r["stderr"][-300:]) for r in results if r["problems"]]
    assert len(results) == 40 and not failed and proc.returncode == 0, (failed, proc.stdout[-2000:])
    assert any(r["status"] == 2 for r in results) and time.monotonic() - t0 > 0


def test_the_oracle_catches_each_failure(fuzz, tmp_path):
    def judged(status=2, stderr="aerial-synth: error: x\n", before=None, after=None, out="ds",
               timed_out=False):
        r = fuzz.Result(0, ["stats"], status, 0.1, stderr, [], timed_out)
        fuzz._judge(r, before or {}, after or {}, out, None, stderr)
        return r.problems

    assert judged() == []
    assert judged(status=0, stderr="") == []
    assert "traceback" in judged(status=1, stderr="Traceback (most recent call last):\nValueError\n")
    assert judged(stderr="aerial-synth: error: a\nsecond line\n") == ["exit 2 with 2 lines on stderr"]
    assert judged(status=1) == ["exit status 1"]
    assert judged(stderr=f"aerial-synth: error: got '{fuzz.SECRET}'\n") == ["the secret behind a link was shown"]
    assert judged(before={"R/labelTxt/a.txt": ("file", "1")}, after={"R/labelTxt/a.txt": ("file", "2")}) == [
        "changed outside --out: R/labelTxt/a.txt"]
    assert judged(after={"ds/x.png": ("file", "1"), ".ds.aerial-synth-lock": ("file", "")}) == []
    assert judged(after={"other/x.png": ("file", "1")}, out=".") == ["changed outside --out: other/x.png"]
    assert judged(status=-signal.SIGKILL, timed_out=True)[0].startswith("did not stop on SIGTERM")
    assert judged(status=143, stderr="aerial-synth: terminated (SIGTERM)\n", timed_out=True) == []


def test_the_runner_reports_a_crash(fuzz, tmp_path, monkeypatch):
    """A command that dies by a signal or prints a traceback is reported, not hidden by the
    fork server."""
    from aerial_synth import cli

    def crash(argv):
        if "--images" in argv:
            os.kill(os.getpid(), signal.SIGSEGV)
        raise ValueError("planted")

    monkeypatch.setattr(cli, "console_main", crash)
    cases = [(("stats",), {"#dir": "@dota", "--out": "st"}), (("render",), dict(fuzz.BASE[("render",)]))]
    results = fuzz.run_cases(cases, tmp_path, jobs=1, timeout=20)
    assert [r.problems[:1] for r in results] == [["traceback"], [f"exit status {-signal.SIGSEGV}"]]
