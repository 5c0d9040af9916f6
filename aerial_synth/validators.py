"""One small set of validators, used by every config, file parser and CLI option.

Each function checks one value and returns it converted (``float``, ``int``, ...), or raises
:class:`~aerial_synth.errors.ConfigError` (or the error class passed as ``error``) with one
line that names the field, says what was expected and shows what arrived::

    spacing.mean_m: expected a finite number > 0, got 'abc'

``field`` is the full name a user would recognise: ``--images``, ``spacing.mean_m``,
``scenes/x.yaml: roads[2].width_m``. Booleans are never numbers here (``True`` is not 1 m).

The ``arg_*`` helpers wrap the same checks as argparse ``type=`` converters, so a bad option
prints ``--images: expected a positive integer, got 'abc'``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from .errors import ConfigError

__all__ = [
    "show",
    "number",
    "finite",
    "positive",
    "non_negative",
    "in_range",
    "probability",
    "integer",
    "one_of",
    "boolean",
    "mapping",
    "sequence_of_numbers",
    "known_keys",
    "arg_int",
    "arg_float",
    "arg_choice",
]


def show(value: Any, limit: int = 60) -> str:
    """A short, unambiguous rendering of an input value for error messages."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _fail(field: str, expected: str, value: Any, error: type[Exception]) -> None:
    raise error(f"{field}: expected {expected}, got {show(value)}")


def number(field: str, value: Any, *, error: type[Exception] = ConfigError,
           expected: str = "a number") -> float:
    """Convert ``value`` to float (numbers and numeric strings; never bools or None)."""
    if isinstance(value, bool) or value is None:
        _fail(field, expected, value, error)
    if isinstance(value, (int, float)):
        try:
            return float(value)
        except OverflowError:  # int too large for a float
            _fail(field, expected, value, error)
    if isinstance(value, str):
        try:
            return float(value.strip())
        except ValueError:
            pass
    try:  # numpy scalars
        import numpy as np

        if isinstance(value, np.generic) and np.issubdtype(type(value), np.number):
            return float(value)
    except ImportError:  # pragma: no cover
        pass
    _fail(field, expected, value, error)
    raise AssertionError  # unreachable


def in_range(field: str, value: Any, lo: float | None = None, hi: float | None = None, *,
             lo_open: bool = False, hi_open: bool = False,
             error: type[Exception] = ConfigError) -> float:
    """A finite number within [lo, hi] (either bound optional, each open or closed)."""
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    expected = "a finite number" + (" " + " and ".join(parts) if parts else "")
    x = number(field, value, error=error, expected=expected)
    if not math.isfinite(x):
        _fail(field, expected, value, error)
    if lo is not None and (x < lo or (lo_open and x == lo)):
        _fail(field, expected, value, error)
    if hi is not None and (x > hi or (hi_open and x == hi)):
        _fail(field, expected, value, error)
    return x


def finite(field: str, value: Any, *, error: type[Exception] = ConfigError) -> float:
    """Any finite number."""
    return in_range(field, value, error=error)


def positive(field: str, value: Any, *, error: type[Exception] = ConfigError) -> float:
    """A finite number > 0."""
    return in_range(field, value, 0.0, lo_open=True, error=error)


def non_negative(field: str, value: Any, *, error: type[Exception] = ConfigError) -> float:
    """A finite number >= 0."""
    return in_range(field, value, 0.0, error=error)


def probability(field: str, value: Any, *, error: type[Exception] = ConfigError) -> float:
    """A number in [0, 1]."""
    return in_range(field, value, 0.0, 1.0, error=error)


def integer(field: str, value: Any, lo: int | None = None, hi: int | None = None, *,
            error: type[Exception] = ConfigError) -> int:
    """An integer (an int, an integral float such as 3.0, or a decimal string) in [lo, hi]."""
    if lo == 1 and hi is None:
        expected = "a positive integer"
    elif lo == 0 and hi is None:
        expected = "a non-negative integer"
    else:
        bounds = []
        if lo is not None:
            bounds.append(f">= {lo}")
        if hi is not None:
            bounds.append(f"<= {hi}")
        expected = "an integer" + (" " + " and ".join(bounds) if bounds else "")
    if isinstance(value, bool) or value is None:
        _fail(field, expected, value, error)
    out: int | None = None
    if isinstance(value, int):
        out = int(value)
    elif isinstance(value, float):
        if math.isfinite(value) and value == int(value):
            out = int(value)
    elif isinstance(value, str):
        try:
            out = int(value.strip(), 10)
        except ValueError:
            out = None
    else:
        try:
            import numpy as np

            if isinstance(value, np.integer):
                out = int(value)
        except ImportError:  # pragma: no cover
            pass
    if out is None or (lo is not None and out < lo) or (hi is not None and out > hi):
        _fail(field, expected, value, error)
    return out  # type: ignore[return-value]


def one_of(field: str, value: Any, choices: Iterable[Any], *,
           error: type[Exception] = ConfigError) -> Any:
    """``value`` if it is one of ``choices``; the error lists them."""
    choices = tuple(choices)
    try:
        ok = value in choices
    except TypeError:  # unhashable
        ok = False
    if not ok:
        _fail(field, "one of " + ", ".join(str(c) for c in choices), value, error)
    return value


def boolean(field: str, value: Any, *, error: type[Exception] = ConfigError) -> bool:
    """A real boolean (YAML true/false); strings like 'maybe' or numbers are refused."""
    if not isinstance(value, bool):
        _fail(field, "true or false", value, error)
    return value


def mapping(field: str, value: Any, *, error: type[Exception] = ConfigError) -> Mapping:
    """A mapping (YAML object)."""
    if not isinstance(value, Mapping):
        _fail(field, "a mapping of key: value", value, error)
    return value


def sequence_of_numbers(field: str, value: Any, n: int | None = None, *, positive_only=False,
                        error: type[Exception] = ConfigError) -> tuple[float, ...]:
    """A list of ``n`` finite numbers (each > 0 with ``positive_only``)."""
    what = "finite numbers" + (" > 0" if positive_only else "")
    expected = f"a list of {n} {what}" if n is not None else f"a list of {what}"
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Iterable):
        _fail(field, expected, value, error)
    items = list(value)
    if n is not None and len(items) != n:
        _fail(field, expected, value, error)
    out = []
    for i, v in enumerate(items):
        check = positive if positive_only else finite
        try:
            out.append(check(f"{field}[{i}]", v, error=error))
        except error:
            _fail(field, expected, value, error)
    return tuple(out)


def known_keys(field: str, data: Mapping, allowed: Iterable[str], *,
               error: type[Exception] = ConfigError) -> None:
    """Refuse keys of ``data`` not in ``allowed``, listing the valid ones."""
    allowed = tuple(allowed)
    unknown = sorted(str(k) if isinstance(k, str) and k.isprintable() and k.strip() == k and k
                     else show(k) for k in data if k not in allowed)
    if unknown:
        raise error(
            f"{field}: unknown key(s) {', '.join(unknown)}; expected one of {', '.join(allowed)}"
        )


# -- argparse converters ---------------------------------------------------------------------


def _argparse_error(exc: Exception):
    import argparse

    # argparse prefixes "argument --name: "; our message already starts with the option name,
    # so the parser's error() strips argparse's prefix (see aerial_synth.cli.Parser).
    return argparse.ArgumentTypeError(str(exc))


def arg_int(option: str, lo: int | None = 1, hi: int | None = None):
    """argparse ``type=``: an integer in [lo, hi] (default: positive)."""

    def conv(text: str) -> int:
        try:
            return integer(option, text, lo, hi)
        except ConfigError as exc:
            raise _argparse_error(exc) from None

    conv.__name__ = "integer"
    return conv


def arg_float(option: str, lo: float | None = None, hi: float | None = None, *,
              lo_open: bool = False, hi_open: bool = False):
    """argparse ``type=``: a finite number within the bounds."""

    def conv(text: str) -> float:
        try:
            return in_range(option, text, lo, hi, lo_open=lo_open, hi_open=hi_open)
        except ConfigError as exc:
            raise _argparse_error(exc) from None

    conv.__name__ = "number"
    return conv


def arg_choice(option: str, choices: Iterable[str]):
    """argparse ``type=``: one of ``choices`` (lists them when refused)."""
    choices = tuple(choices)

    def conv(text: str) -> str:
        try:
            return one_of(option, text, choices)
        except ConfigError as exc:
            raise _argparse_error(exc) from None

    conv.__name__ = "choice"
    return conv
