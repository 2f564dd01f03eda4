"""`pamd model export --fis` against a readfis that is not pamd's: GNU Octave's
fuzzy-logic-toolkit (a free reimplementation of MATLAB's Fuzzy Logic Toolbox functions)
reads the exported file, evaluates it at random points inside the model's ranges, and
writes it back with its own writefis, which `pamd model import` reads in turn. Prints
the largest difference each way, in the output's unit.

    python bench/fis_octave.py MODEL.json     # needs octave and its fuzzy-logic-toolkit
                                              # (Debian: apt install octave
                                              #  octave-fuzzy-logic-toolkit)

Octave's toolkit takes only whole-number gbellmf slopes b (MATLAB's gbellmf, and its
anfis, any real b): a bell model with slopes in between is refused by Octave, not by
MATLAB. Measured (issue 40, a shared 2-core PC): the walk-through's 3-input Gaussian
model 3.1e-9 bar each way from evalfis (the raw-unit consequents' cancellation: 2e-12
of the pressure), a bell model with whole slopes 8.9e-15 bar, a constant forward model
4.9e-15 N; Octave's writefis (15 digits) read back 2.3e-8 bar, 1e-13 bar, 2.3e-5 N.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from pamd.models.fis import export_fis, import_fis
from pamd.models.registry import load_model

SCRIPT = """pkg load fuzzy-logic-toolkit
fis = readfis('model.fis');
y = evalfis(load('X.txt'), fis);
dlmwrite('y_octave.txt', y(:), 'precision', 17);
writefis(fis, 'octave.fis');
printf('%s: %s, %d inputs, %d rules\\n', fis.name, fis.type, numel(fis.input), numel(fis.rule));
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", help="a pamd model file of kind anfis or ts-fuzzy")
    ap.add_argument("--points", type=int, default=500)
    a = ap.parse_args()
    octave = shutil.which("octave")
    if octave is None:
        sys.exit("octave is not installed (apt install octave octave-fuzzy-logic-toolkit)")
    model = load_model(a.model)
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(v.min, v.max, a.points) for v in model.inputs])
    with tempfile.TemporaryDirectory(prefix="pamd-fis-") as tmp:
        d = Path(tmp)
        export_fis(model, d / "model.fis")
        np.savetxt(d / "X.txt", X, fmt="%.17g")
        (d / "check.m").write_text(SCRIPT)
        r = subprocess.run([octave, "--no-gui", "--quiet", "check.m"], cwd=d,
                           capture_output=True, text=True, timeout=600)
        if not (d / "y_octave.txt").exists():
            sys.exit(f"octave failed:\n{r.stdout}\n{r.stderr}")
        print("octave readfis:", r.stdout.strip().splitlines()[0])
        y_octave = np.loadtxt(d / "y_octave.txt")
        y_pamd = model.predict(X)
        back = import_fis(d / "octave.fis").model
        unit = model.output.unit
        print(f"evalfis (Octave) - pamd: max |difference| "
              f"{np.max(np.abs(y_octave - y_pamd)):.3g} {unit} over {a.points} points")
        print(f"pamd import of Octave's writefis - pamd: max |difference| "
              f"{np.max(np.abs(back.predict(X) - y_pamd)):.3g} {unit} (Octave writes 15 "
              "significant digits)")


if __name__ == "__main__":
    main()
