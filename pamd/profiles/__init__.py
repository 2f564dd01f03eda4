"""Profiles: a pressure (or length) setpoint over time, and the registry of their
shapes.

Every profile starts with a lead-in ramp from the present value to its own start
value, then runs its shape: constant, step (a square wave whose edges are ramps),
ramp, sine (the seeds' (p/2) sin + p/2: starts at mid-range rising with maximum
slope), triangle, or seed 003's two test signals of several harmonics, multisine
(its "complex harmonic signal") and multitriangle (its "complex triangular wave"),
for a number of cycles (None: until stopped). `sample(t)` sets
`value`, `rate`, `cycle` and `done` without allocating; `check()` refuses a
profile that is faster than the slew limit or leaves the allowed range.

A shape is one `Shape` subclass, registered in `SHAPES`: its name, its own checks and
its evaluator; its name and the `ProfileSpec` fields it reads are declared in
`pamd.wire.shape_names` (light: the command schemas in the io process read only that).
The command schema, experiment plans, `pamd run --profile` and length profiles take
their shapes from there.

shapes     `Shape` and the plain shapes: constant, ramp, step, sine, triangle
harmonic   seed 003's sums of harmonics: multisine, multitriangle
spec       `ProfileSpec` (what is asked for, checked before anything moves), the
           registry `SHAPES`, and `Profile`, a running profile sampled in the tick
"""

from pamd.profiles.harmonic import (
    DEFAULT_HARMONICS,
    HARMONIC_GRID,
    Harmonic,
    Multisine,
    Multitriangle,
    unit_triangle,
)
from pamd.profiles.shapes import Constant, Periodic, Ramp, Shape, Sine, Step, Triangle
from pamd.profiles.spec import MAX_PROFILE_S, SHAPES, Profile, ProfilePoint, ProfileSpec, shape_of
from pamd.wire.shape_names import SHAPE_NAMES, ShapeName, shapes_reading, shapes_text

__all__ = [
    "DEFAULT_HARMONICS", "HARMONIC_GRID", "MAX_PROFILE_S", "SHAPES", "SHAPE_NAMES", "Constant",
    "Harmonic", "Multisine", "Multitriangle", "Periodic", "Profile", "ShapeName",
    "ProfilePoint", "ProfileSpec", "Ramp", "Shape", "Sine", "Step", "Triangle", "shapes_reading",
    "shapes_text", "shape_of", "unit_triangle",
]
