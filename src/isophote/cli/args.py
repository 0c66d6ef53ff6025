"""Argument types and the flags generated from the option dataclasses.

Nothing here imports more than the standard library and :mod:`isophote.options`, so that
building a parser stays instant (``isophote --help`` is benchmarked).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import MISSING, fields


# =============================================================================================
# Types: comma-separated numbers
# =============================================================================================


def _parts(text: str) -> list:
    return [v for v in text.replace(" ", "").split(",") if v != ""]


def finite_floats(parts) -> tuple:
    """The numbers in ``parts``, or () if one is not a finite number."""
    try:
        values = tuple(float(v) for v in parts)
    except ValueError:
        return ()
    return values if all(math.isfinite(v) for v in values) else ()


def float_list(text: str) -> tuple:
    try:
        values = tuple(float(v) for v in _parts(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def numbers(count, what: str | None = None):
    """argparse type: comma-separated numbers, ``count`` of them (an int or a tuple of ints);
    ``what`` names them in the error (e.g. 'X,Y,W,H')."""
    counts = (count,) if isinstance(count, int) else tuple(count)

    def parse(text: str) -> tuple:
        values = finite_floats(_parts(text))
        if len(values) not in counts:
            want = " or ".join(str(c) for c in counts)
            named = f"{what} ({want} numbers)" if what else f"{want} numbers separated by commas"
            raise argparse.ArgumentTypeError(f"expected {named}, got {text!r}")
        return values

    return parse


crop = numbers(4, "X,Y,W,H")


def positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


# =============================================================================================
# Flags generated from an options dataclass
# =============================================================================================


def check_table(cls, table) -> None:
    """Every flag of ``table`` names a field of ``cls`` (caught at import, not by a user)."""
    unknown = set(table) - {f.name for f in fields(cls)}
    assert not unknown, f"flags for unknown {cls.__name__} fields: {unknown}"


def add_option_flags(parser, cls, table, names=None) -> None:
    """One --flag per dataclass field in ``table``; absent flags leave the field default,
    which the help text shows (read from the dataclass, never written here)."""
    defaults = {f.name: f.default for f in fields(cls) if f.default is not MISSING}
    for name in names if names is not None else table:
        kw = dict(table[name])
        default = defaults.get(name)
        if default is not None and "(default" not in kw.get("help", ""):
            kw["help"] = f"{kw.get('help', '')} (default: {default})"
        parser.add_argument("--" + name.replace("_", "-"), dest=name, default=argparse.SUPPRESS, **kw)


def options(args, cls, table):
    """The dataclass built from the flags that were given (defaults stay in the dataclass)."""
    return cls(**{name: getattr(args, name) for name in table if hasattr(args, name)})


def defaults_of(module: str, function: str) -> dict:
    """The keyword defaults of ``module.function`` (a relative name is isophote's), for the
    flags of a library function that has no options dataclass."""
    import importlib
    import inspect

    fn = getattr(importlib.import_module(module, __package__), function)
    return {k: v.default for k, v in inspect.signature(fn).parameters.items() if v.default is not v.empty}
