"""The CLI foundation: one-line usage errors (exit 2), output paths that are never replaced
when they are not regular files, file-system refusals as one line, and the validators."""

from __future__ import annotations

import math
import os
import stat

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aerial_synth import validators as v
from aerial_synth.cli import main, one_line_usage_error
from aerial_synth.errors import ConfigError, OutputError
from aerial_synth.io_utils import (
    atomic_write_bytes,
    check_output_dir,
    check_output_file,
    is_inside,
)


def _run(capsys, *argv):
    code = main(list(argv))
    err = capsys.readouterr().err
    return code, err


def _device(tmp_path, name="dev"):
    """A character device (or a FIFO where mknod is not allowed) inside tmp_path."""
    p = tmp_path / name
    try:
        os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except (PermissionError, OSError):
        os.mkfifo(p)
    return p


def _snapshot(folder):
    return sorted((str(p.relative_to(folder)), p.lstat().st_mode) for p in folder.rglob("*"))


# --------------------------------------------------------------------- argparse, one line
@pytest.mark.parametrize(
    "argv, expected",
    [
        (["export", "--images", "abc", "--out", "x"],
         "aerial-synth export: --images: expected an integer >= 1 and <= 1000000, got 'abc'"),
        (["place", "--seed", "1.5"], "aerial-synth place: --seed: expected a non-negative integer, got '1.5'"),
        (["export"], "aerial-synth export: missing required --out"),
        (["export", "--images", "99999999999999999999", "--out", "x"],
         "aerial-synth export: --images: expected an integer >= 1 and <= 1000000, got"),
        (["place", "--traffic", "up"],
         "aerial-synth place: --traffic: expected one of right, left, got 'up'"),
        (["assets", "preview", "--out", "a.png", "--gsd", "nan"],
         "aerial-synth assets preview: --gsd: expected a finite number >= 0.005 and <= 0.5, got 'nan'"),
        (["place", "--no-such-option"], "aerial-synth: unrecognized arguments: --no-such-option"),
        (["nosuchcommand"], "aerial-synth: --"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(capsys, argv, expected):
    code, err = _run(capsys, *argv)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    if expected.endswith("--"):
        assert lines[0].startswith("aerial-synth: ")
    else:
        assert lines[0].startswith(expected), lines[0]
    assert "--help" in lines[0] and "usage:" not in err


def test_help_still_exits_0(capsys):
    assert main(["--help"]) == 0
    assert "usage:" in capsys.readouterr().out


def test_message_rewriting_table():
    f = one_line_usage_error
    assert f("p", "argument --n: invalid int value: 'x'") == "p: --n: expected an integer, got 'x' (see 'p --help')"
    assert f("p", "argument --f: invalid float value: 'x'").startswith("p: --f: expected a number, got 'x'")
    assert f("p", "argument --n: --n: expected a positive integer, got '0'").startswith(
        "p: --n: expected a positive integer, got '0'")
    assert "\n" not in f("p", "argument --c: invalid choice: 'z' (choose from 'a', 'b',\n 'c')")


# --------------------------------------------------------------------- outputs
def test_atomic_write_never_replaces_a_device(tmp_path):
    dev = _device(tmp_path)
    before = dev.lstat()
    with pytest.raises(OutputError, match="expected a regular file"):
        atomic_write_bytes(dev, b"x")
    after = dev.lstat()
    assert (before.st_mode, before.st_ino) == (after.st_mode, after.st_ino)
    assert [p.name for p in tmp_path.iterdir()] == ["dev"]  # no temp file left


@pytest.mark.parametrize("cmd", [
    ["scene", "show", "city_park", "--out"],
    ["scene", "export", "city_park", "--out"],
    ["assets", "preview", "--out"],
])
def test_writing_commands_refuse_a_device_output(capsys, tmp_path, cmd):
    name = "out.glb" if "export" in cmd else "out.png"
    dev = _device(tmp_path, name)
    before = _snapshot(tmp_path)
    code, err = _run(capsys, *cmd, str(dev))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert str(dev) in err
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("cmd", [
    ["scene", "show", "city_park", "--out"],
    ["assets", "preview", "--out"],
])
def test_writing_commands_refuse_a_path_below_a_file(capsys, tmp_path, cmd):
    (tmp_path / "afile").write_text("keep")
    code, err = _run(capsys, *cmd, str(tmp_path / "afile" / "sub" / "x.png"))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert (tmp_path / "afile").read_text() == "keep"


def test_check_output_file_and_dir(tmp_path):
    (tmp_path / "f").write_text("x")
    (tmp_path / "d").mkdir()
    assert check_output_file(tmp_path / "f") == tmp_path / "f"
    assert check_output_file(tmp_path / "new" / "deeper" / "x.png")
    assert check_output_dir(tmp_path / "d") == tmp_path / "d"
    assert check_output_dir(tmp_path / "new" / "deeper")
    with pytest.raises(OutputError, match="found a folder"):
        check_output_file(tmp_path / "d")
    with pytest.raises(OutputError, match="expected a folder, found a file"):
        check_output_dir(tmp_path / "f")
    with pytest.raises(OutputError, match="found a file"):
        check_output_dir(tmp_path / "f" / "sub")
    with pytest.raises(OutputError, match="found a file"):
        check_output_file(tmp_path / "f" / "sub" / "x.txt")
    dev = _device(tmp_path)
    with pytest.raises(OutputError, match="expected a folder, found a (character device|FIFO)"):
        check_output_dir(dev)
    link = tmp_path / "link.png"
    link.symlink_to(dev)
    with pytest.raises(OutputError):
        check_output_file(link)
    assert is_inside(tmp_path / "d" / "x", tmp_path / "d") and not is_inside(tmp_path, tmp_path / "d")


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores file modes; read-only folders "
                    "cannot be tested as root")
def test_read_only_folder_is_refused(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(OutputError, match="not writable"):
            check_output_file(ro / "x.png")
        code, err = _run(capsys, "scene", "show", "city_park", "--out", str(ro / "x.png"))
        assert code == 2 and len(err.strip().splitlines()) == 1
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def test_os_errors_from_commands_are_one_line(capsys, monkeypatch):
    import aerial_synth.cli as cli

    def boom(args):
        raise PermissionError(13, "Permission denied", "/somewhere/x.png")

    parser = cli.build_parser()
    args = parser.parse_args(["assets", "list"])
    args.func = boom
    monkeypatch.setattr(cli.Parser, "parse_args", lambda self, argv=None: args)
    assert cli.main(["assets", "list"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "aerial-synth: error: /somewhere/x.png: Permission denied"


# --------------------------------------------------------------------- validators
@pytest.mark.parametrize("fn, value, ok", [
    (v.positive, 1, 1.0), (v.positive, "2.5", 2.5), (v.positive, 0, None), (v.positive, -1, None),
    (v.positive, "abc", None), (v.positive, float("nan"), None), (v.positive, float("inf"), None),
    (v.positive, True, None), (v.positive, None, None), (v.positive, [1], None),
    (v.non_negative, 0, 0.0), (v.non_negative, -1e-9, None),
    (v.probability, 1, 1.0), (v.probability, 1.0001, None), (v.finite, -3, -3.0),
    (v.finite, 10**400, None),
])
def test_number_validators_table(fn, value, ok):
    if ok is None:
        with pytest.raises(ConfigError, match=r"^f: expected .*, got "):
            fn("f", value)
    else:
        assert fn("f", value) == ok


@pytest.mark.parametrize("value, lo, ok", [
    (3, 0, 3), ("7", 1, 7), (2.0, 0, 2), (2.5, 0, None), ("1.5", 0, None), (-1, 0, None),
    (0, 1, None), (True, 0, None), ("x", 0, None), (float("nan"), 0, None),
])
def test_integer_validator_table(value, lo, ok):
    if ok is None:
        with pytest.raises(ConfigError, match="^n: expected"):
            v.integer("n", value, lo)
    else:
        assert v.integer("n", value, lo) == ok


def test_other_validators():
    assert v.one_of("k", "a", ("a", "b")) == "a"
    with pytest.raises(ConfigError, match="k: expected one of a, b, got 'c'"):
        v.one_of("k", "c", ("a", "b"))
    with pytest.raises(ConfigError, match="expected one of"):
        v.one_of("k", ["unhashable"], ("a",))
    assert v.boolean("b", False) is False
    with pytest.raises(ConfigError, match="b: expected true or false, got 'maybe'"):
        v.boolean("b", "maybe")
    assert v.sequence_of_numbers("s", [1, "2"], 2, positive_only=True) == (1.0, 2.0)
    with pytest.raises(ConfigError, match=r"s: expected a list of 2 finite numbers > 0, got \['abc', 100\]"):
        v.sequence_of_numbers("s", ["abc", 100], 2, positive_only=True)
    with pytest.raises(ConfigError, match="unknown key"):
        v.known_keys("m", {"a": 1, "zz": 2}, ("a", "b"))


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True),
                 st.text(max_size=8), st.lists(st.integers(), max_size=2),
                 st.dictionaries(st.text(max_size=2), st.integers(), max_size=2)))
def test_validators_never_raise_anything_but_config_error(value):
    for fn in (v.positive, v.non_negative, v.finite, v.probability):
        try:
            out = fn("f", value)
        except ConfigError as exc:
            assert "\n" not in str(exc)
        else:
            assert isinstance(out, float) and math.isfinite(out)
    try:
        out = v.integer("n", value, 0)
    except ConfigError:
        pass
    else:
        assert isinstance(out, int) and out >= 0


def test_library_warnings_are_one_line():
    from aerial_synth.cli import _one_line_warning

    text = _one_line_warning(UserWarning("a\nb"), UserWarning, "f.py", 3)
    assert text == "aerial-synth: warning: a b\n"


def test_empty_output_path_is_refused_not_taken_as_cwd(tmp_path):
    with pytest.raises(OutputError, match="expected a folder path, got ''"):
        check_output_dir("")
    with pytest.raises(OutputError, match="expected a file path, got ''"):
        check_output_file("")
