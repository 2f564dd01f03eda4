"""The profile shapes' names and the `ProfileSpec` fields each reads: what a command's
schema, a plan's `shape` and `pamd run --help` need of the shapes, without their code
(`pamd.profiles`). The io process validates commands with this module alone.

A new shape is one line here and one `pamd.profiles.Shape` subclass registered in
`pamd.profiles.spec` (whose `SHAPES` takes its order from here; a test checks that
the two name the same shapes).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

#: What multisine and multitriangle read: a periodic shape's fields and the harmonics.
HARMONIC_PARAMS: tuple[str, ...] = ("min_bar", "max_bar", "freq_hz", "cycles", "harmonics")
#: Every profile shape by name, in the order the operator reads them, with the
#: ProfileSpec fields it reads (beyond lead_in_bar_per_s).
SHAPE_PARAMS: dict[str, tuple[str, ...]] = {
    "constant": ("to_bar", "duration_s"),
    "step": ("min_bar", "max_bar", "freq_hz", "cycles", "rise_s"),
    "ramp": ("to_bar", "rate_bar_per_s"),
    "sine": ("min_bar", "max_bar", "freq_hz", "cycles"),
    "triangle": ("min_bar", "max_bar", "freq_hz", "cycles"),
    "multisine": HARMONIC_PARAMS,
    "multitriangle": HARMONIC_PARAMS,
}

SHAPE_NAMES: tuple[str, ...] = tuple(SHAPE_PARAMS)

if TYPE_CHECKING:
    ShapeName = str
else:  # the config engine validates a plan's `shape` against the registered names
    ShapeName = Literal[SHAPE_NAMES]


def shapes_text() -> str:
    """The shapes for an operator: 'constant, step, ramp, sine or triangle'."""
    return ", ".join(SHAPE_NAMES[:-1]) + " or " + SHAPE_NAMES[-1]


def shapes_reading(param: str, sep: str = ", ") -> str:
    """The shapes that read ProfileSpec field `param` (help texts)."""
    return sep.join(name for name, params in SHAPE_PARAMS.items() if param in params)
