"""`aerial-synth --help` starts fast: it imports no command module (each imports numpy and
more to state its defaults), only the named command's module is imported to run it, and the
help it prints is the help the modules register."""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys

import pytest

from aerial_synth import cli

#: modules a bare `python -c pass` has, plus what cli.py itself needs (argparse, pathlib,
#: the --out guard); every command module imported put it at ~300 (numpy alone is ~130)
MAX_MODULES_FOR_HELP = 130

_COUNT = ("import sys, io, contextlib\n"
          "from aerial_synth import cli\n"
          "with contextlib.redirect_stdout(io.StringIO()):\n"
          "    code = cli.main(sys.argv[1:])\n"
          "print(code, len(sys.modules), ' '.join(sorted(m for m in ('numpy', 'shapely', 'yaml', "
          "'open3d', 'aerial_synth.placement', 'aerial_synth.vehicles', 'aerial_synth.dataset') "
          "if m in sys.modules)))\n")


def _imported(*argv):
    r = subprocess.run([sys.executable, "-c", _COUNT, *argv], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    code, n, *heavy = r.stdout.split()
    return int(code), int(n), heavy


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["plase"]])
def test_help_imports_no_command_module(argv):
    code, n, heavy = _imported(*argv)
    assert code == (2 if argv == ["plase"] else 0)
    assert heavy == [] and n <= MAX_MODULES_FOR_HELP, (n, heavy)


def test_a_command_imports_its_own_module_only():
    code, n, heavy = _imported("assets", "--help")
    assert code == 0 and "aerial_synth.vehicles" in heavy
    assert "aerial_synth.dataset" not in heavy and "aerial_synth.placement" not in heavy


def test_command_table_is_what_the_modules_register():
    """cli.COMMANDS (name, module, help, order) against the modules' own register()."""
    got = []
    for module in dict.fromkeys(m for m, _ in cli.COMMANDS.values()):
        p = argparse.ArgumentParser()
        sub = p.add_subparsers(dest="command")
        importlib.import_module(module).register(sub)
        got += [(a.dest, module, a.help) for a in sub._choices_actions]
    assert got == [(k, m, h) for k, (m, h) in cli.COMMANDS.items()]


def test_help_lists_every_command_and_a_command_help_has_its_options(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for name, (_, help_) in cli.COMMANDS.items():
        assert name in out and " ".join(help_.split()[:3]) in " ".join(out.split())
    assert cli.main(["place", "--help"]) == 0
    assert "--scenario" in capsys.readouterr().out
