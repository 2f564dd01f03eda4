"""A command-line number taken as the config and command schemas take one: finite, of
a physical size (not subnormal), inside its unit's domain (`pamd.wire.schema.domains`) and
the option's own bounds. An argparse `type`, so a bad value is a usage error before
anything opens: `--duration 1e-320`, `--duration nan` and `--duration -1` alike."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from pamd.wire.schema.domains import FieldMeta
from pamd.wire.schema.engine import Context, build


def number(unit: str = "", **bounds: float) -> Callable[[str], float]:
    """An argparse type for a number in `unit` (s, Hz, bar, ...) within `bounds`
    (`gt`, `min`, `max`: as a schema field declares them)."""
    meta: FieldMeta = {"unit": unit} if unit else {}
    for key in ("gt", "min", "max"):
        if key in bounds:
            meta[key] = bounds[key]

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, found {text!r}") from None
        ctx = Context("")
        built = build(float, value, ctx, "", None, meta)
        if ctx.issues:
            raise argparse.ArgumentTypeError(
                f"expected {ctx.issues[0].expected}, found {ctx.issues[0].found}")
        return float(built)

    parse.__name__ = "number"  # argparse's "invalid number value: ..."
    return parse
