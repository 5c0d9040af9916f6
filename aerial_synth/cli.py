"""Command-line entry point: ``aerial-synth``.

Thin: parse arguments, call the API, print a short summary. Every subcommand lives in the
``cli`` module of its package and registers itself with :func:`register`; those modules
import nothing heavy at import time so ``aerial-synth --help`` stays instant.
User mistakes (:class:`AerialSynthError`) print one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import re
import sys
from contextlib import contextmanager

from . import __version__
from ._open3d import stub_viewer
from .errors import AerialSynthError
from .out_guard import INPUT_OPTIONS, out_lock, refuse_out_is_input
from .safe_input import input_roots

_ARG_PREFIX = re.compile(r"^argument (?P<opt>[^:]+): (?P<msg>.*)$", re.S)
_INVALID_VALUE = re.compile(r"^invalid (?P<kind>int|float|\w+) value: (?P<got>.*)$", re.S)
_INVALID_CHOICE = re.compile(r"^invalid choice: (?P<got>.*?) \(choose from (?P<choices>.*)\)$", re.S)
_EXPECTED = {"int": "an integer", "float": "a number"}


def one_line_usage_error(prog: str, message: str) -> str:
    """Turn an argparse message into ``PROG: --opt: expected ..., got ...`` (one line)."""
    m = _ARG_PREFIX.match(message)
    if m:
        opt = m.group("opt").split("/")[-1]
        msg = m.group("msg")
        if msg.startswith(opt + ":"):
            text = msg  # our own converters already name the option
        elif (v := _INVALID_VALUE.match(msg)):
            text = f"{opt}: expected {_EXPECTED.get(v.group('kind'), 'a value')}, got {v.group('got')}"
        elif (c := _INVALID_CHOICE.match(msg)):
            choices = c.group("choices").replace("'", "")
            text = f"{opt}: expected one of {choices}, got {c.group('got')}"
        else:
            text = f"{opt}: {msg}"
    elif message.startswith("the following arguments are required: "):
        text = "missing required " + message.split(": ", 1)[1]
    else:
        text = message
    text = " ".join(text.split())  # one line, whatever argparse wrapped
    return f"{prog}: {text} (see '{prog} --help')"


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line and exit status 2 (no usage block)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        print(one_line_usage_error(self.prog, message), file=sys.stderr)
        sys.exit(2)


#: Each command's module and one-line help, in the order of ``--help``: ``aerial-synth
#: --help`` and a mistyped command print these without importing a command module (each
#: imports numpy and more to state its defaults; 0.5 s of a cold start). A test holds them
#: equal to what the modules register.
COMMANDS = {
    "scene": ("aerial_synth.scene.cli", "list, show and export scenes"),
    "assets": ("aerial_synth.vehicles.cli",
               "vehicle catalog: list models, draw a contact sheet of every variant"),
    "place": ("aerial_synth.placement.cli",
              "place vehicles on roads with line traces (jam, normal, sparse, random)"),
    "place-tiled": ("aerial_synth.placement.tiled_cli",
                    "place vehicles tile by tile on a large world (city of size_km, big meshes)"),
    "render": ("aerial_synth.render.cli",
               "render frames (RGB, instance, semantic, depth, meta) of a placed scene"),
    "export": ("aerial_synth.dataset.cli",
               "export a labelled dataset (DOTA, EAGLE-style, YOLO-OBB, COCO)"),
    "show": ("aerial_synth.dataset.cli", "draw a dataset's labels over its images, plus a contact sheet"),
    "eval": ("aerial_synth.evaluate.cli",
             "oriented-box average precision of predictions against DOTA ground truth"),
    "mix": ("aerial_synth.evaluate.cli",
            "mix real and synthetic images into one training set (deterministic, linked)"),
    "stats": ("aerial_synth.evaluate.cli", "dataset statistics and, with --compare, the domain-gap report"),
    "sim2real": ("aerial_synth.sim2real.cli",
                 "what the data is worth: train a detector per synthetic set, score it on real images"),
}


def _command_of(argv: list[str]) -> str | None:
    """The command named on a command line (its first word that is not an option)."""
    for a in argv:
        if not a.startswith("-"):
            return a
        if a == "--":
            break
    return None


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The full parser; with ``argv``, only the named command's module is imported (the
    others are listed by name and help: enough for ``--help``, ``--version`` and the one
    line that a mistyped command gets)."""
    parser = Parser(
        prog="aerial-synth",
        description="Synthetic nadir aerial images of vehicles with exact oriented-box labels.",
    )
    parser.add_argument("--version", action="version", version=f"aerial-synth {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    wanted = None if argv is None else COMMANDS.get(_command_of(argv), (None,))[0]
    done = set()
    for name, (module, help_) in COMMANDS.items():
        if argv is None or module == wanted:
            if module not in done:
                importlib.import_module(module).register(sub)
                done.add(module)
        else:
            sub.add_parser(name, help=help_)
    return parser


_USER_ERRNOS = {
    errno.EACCES, errno.EPERM, errno.EEXIST, errno.ENOTDIR, errno.EISDIR, errno.ENOENT,
    errno.ENOSPC, errno.EROFS, errno.ENAMETOOLONG, errno.ELOOP, errno.EDQUOT,
}


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """Warnings from the library print as one line, like errors (no source line)."""
    return f"aerial-synth: warning: {_one_line(str(message))}\n"


def console_main(argv: list[str] | None = None) -> int:
    """The ``aerial-synth`` command: :func:`main` in a process of its own, which imports
    open3d without its plotly viewer (:mod:`aerial_synth._open3d`: ~0.4 s less start-up
    for every command that casts rays)."""
    stub_viewer()
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")  # our one line, not OpenCV's log too
    for stream in (sys.stdout, sys.stderr):  # a file name with bytes that are not UTF-8,
        try:                                 # printed under a UTF-8 locale: escaped, no crash
            stream.reconfigure(errors="backslashreplace")
        except (AttributeError, ValueError):
            pass
    return main(argv)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the command runs: it unwinds as Ctrl-C does (a pool
    is stopped, temporary files are removed), then the CLI prints one line and exits with
    the shell's status for the signal (128 + its number: 143, 129)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)


#: The signal being delivered as :class:`Terminated`, until the CLI has caught it. A library
#: that catches BaseException around its own imports (trimesh does, for its optional
#: dependencies) swallowed it once: ``scene from-osm`` then finished, wrote its output and
#: exited 0. While it is pending, SIGALRM raises it again every :data:`REMIND_S` (the
#: SIGALRM handler and timer in place before, a test runner's for one, come back after).
_PENDING: list[int] = []
_SAVED_ALARM: list[tuple] = []
REMIND_S = 0.25


def _raise(signum: int):
    import signal

    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


def _remind(signum, frame):
    if _PENDING:
        _raise(_PENDING[0])


def _on_terminate(main_pid: int):
    def handler(signum, frame):
        import signal

        if os.getpid() != main_pid:  # a forked worker that kept this handler: as before
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        if not _PENDING:
            _PENDING.append(int(signum))
            try:
                old = signal.signal(signal.SIGALRM, _remind)
                _SAVED_ALARM.append((old, signal.setitimer(signal.ITIMER_REAL, REMIND_S, REMIND_S)))
            except (AttributeError, ValueError, OSError):  # pragma: no cover - no timers
                pass
        _raise(signum)

    return handler


def _disarm() -> None:
    """The pending termination has reached the CLI: no more reminders; the SIGALRM handler
    and timer from before come back."""
    import signal

    _PENDING.clear()
    while _SAVED_ALARM:
        handler, (delay, interval) = _SAVED_ALARM.pop()
        try:
            signal.setitimer(signal.ITIMER_REAL, 0, 0)
            signal.signal(signal.SIGALRM, handler)
            if delay:
                signal.setitimer(signal.ITIMER_REAL, delay, interval)
        except (AttributeError, ValueError, OSError, TypeError):  # pragma: no cover
            pass


@contextmanager
def _terminate_as_interrupt():
    """SIGTERM and SIGHUP raise :class:`Terminated` in this process for the body, SIGINT
    KeyboardInterrupt (unless it is ignored, as in a shell's background job); until the CLI
    catches it, it is raised again every :data:`REMIND_S` (the previous handlers come back
    after the body)."""
    import signal

    sigs = [getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n)]
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        sigs.append(signal.SIGINT)
    previous = {}
    try:
        for s in sigs:
            previous[s] = signal.signal(s, _on_terminate(os.getpid()))
    except ValueError:  # not the main thread: leave signals alone
        pass
    try:
        yield
    finally:
        if previous:
            _disarm()
        for s, h in previous.items():
            signal.signal(s, h)


def main(argv: list[str] | None = None) -> int:
    import warnings

    previous = warnings.formatwarning
    warnings.formatwarning = _one_line_warning  # the CLI's own process (and forked workers)
    try:
        with _terminate_as_interrupt():
            return _main(argv)
    finally:
        warnings.formatwarning = previous  # main() called as a function leaves no trace


def _main(argv: list[str] | None) -> int:
    try:  # a signal during the imports of build_parser: one line too
        parser = build_parser(sys.argv[1:] if argv is None else list(argv))
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage error (one line, printed) or --help/--version
        return int(exc.code or 0) if not isinstance(exc.code, str) else 2
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    try:
        refuse_out_is_input(args)
        with _out_locked(args), input_roots(getattr(args, d, None) for d in INPUT_OPTIONS):
            code = int(args.func(args) or 0)
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        # the reader went away (`aerial-synth assets list | head`): stop quietly, as Unix
        # tools do; point stdout at devnull so the interpreter's final flush is silent too
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except AerialSynthError as exc:
        if _PENDING:  # a library swallowed the signal and failed on: it was the signal
            return _interrupted(_signal_exc(_PENDING[0]))
        print(f"aerial-synth: error: {_one_line(str(exc))}", file=sys.stderr)
        return 2
    except OSError as exc:
        if _PENDING:
            return _interrupted(_signal_exc(_PENDING[0]))
        # A file-system refusal on an output or input path is the user's to fix: one line.
        if exc.errno in _USER_ERRNOS:
            where = exc.filename if exc.filename is not None else ""
            if exc.errno in (errno.ENOSPC, errno.EDQUOT) and getattr(args, "out", None) is not None:
                # a full disk is the output's: a copy names its source file first (shutil)
                where = f"--out {args.out}"
            elif not where and getattr(args, "out", None) is not None:
                where = f"--out {args.out}"  # a failed write names no file
            print(f"aerial-synth: error: {where}: {exc.strerror or exc}".replace(": : ", ": "),
                  file=sys.stderr)
            return 2
        raise
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    except Exception as exc:
        if _PENDING:  # trimesh, having swallowed Terminated on an import, failed later
            return _interrupted(_signal_exc(_PENDING[0]))
        if isinstance(exc, RuntimeError) and str(exc).startswith("Symlink loop from "):
            # pathlib's resolve() in a library: the path is the user's to fix
            print(f"aerial-synth: error: {str(exc)[len('Symlink loop from '):].strip(chr(39))}: "
                  "a loop of symbolic links", file=sys.stderr)
            return 2
        raise


#: The one-line refusal of a second writer, per command (default: out_guard's own).
_BUSY = {"export": "--out {out}: another aerial-synth export is writing this folder right now; "
                   "wait for it to finish or choose another folder"}


def _out_locked(args):
    """The ``--out`` lock of every command that writes (:func:`out_guard.out_lock`): taken
    here, around the command, so no writing command can forget it (issue 37 K1)."""
    from contextlib import nullcontext

    out = getattr(args, "out", None)
    if not isinstance(out, (str, os.PathLike)):
        return nullcontext()
    busy = _BUSY.get(getattr(args, "command", None) or "")
    return out_lock(out, str(getattr(args, "command", "aerial-synth")),
                    busy=busy.format(out=out) if busy else None, outer=True)


def _signal_exc(signum: int) -> KeyboardInterrupt:
    import signal

    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def _interrupted(exc: KeyboardInterrupt) -> int:
    """Ctrl-C, SIGTERM or SIGHUP reached the CLI: one line, the shell's status."""
    import signal

    _disarm()
    if isinstance(exc, Terminated):
        print(f"aerial-synth: terminated ({signal.Signals(exc.signum).name})", file=sys.stderr)
        return 128 + exc.signum
    print("aerial-synth: interrupted", file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(console_main())
