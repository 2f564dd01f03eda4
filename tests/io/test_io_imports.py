"""The io process, as actually spawned, imports only what it needs: the recorder, the
Zenoh node and the command schemas, never the controller, the models, the loop's
command handlers, the config engine's rig schema, the YAML loader, the CLI or numpy.

A real recorded run with telemetry is started through the console script (generated
from pyproject's `[project.scripts]` as pip writes it: multiprocessing's spawn runs the
parent's main module again in the child, so what the console script imports at its
top is what the io process pays for). The io process writes the modules it imported as
it exits (`pamd.iohost.process.MODULES_ENV`, a test hook).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

from pamd.emulate.testing import free_port
from pamd.iohost.process import MODULES_ENV

ROOT = Path(__file__).resolve().parents[2]

#: at most this many of pamd's modules (packages included) in the io process, the 4 of
#: `pamd.wire.declare` (the field table, the event registry and the JSON encoder the
#: recorder and the node are built from) among them: #26 asks for 40. Was 191 before
#: the split, 44 before the node's ports became types only and the YAML loader stayed
#: out, 40 before issue 41's move (38 after it).
MAX_PAMD_MODULES = 40

#: at most this many first-level names under pamd (issue 41): `pamd` itself, the
#: console script's module `pamd.__main__`, what crosses the processes (`pamd.wire`)
#: and the io process's own package (`pamd.iohost`). Was 12 before the move.
MAX_FIRST_LEVEL = 4

#: never in the io process: the other processes' packages (the loop's, the main
#: process's, the client's), the libraries (models, config, drivers, the sim), numpy
FORBIDDEN = ("pamd.loop", "pamd.daemon", "pamd.client", "pamd.models", "pamd.config",
             "pamd.drivers", "pamd.sim", "pamd.emulate", "pamd.profiles", "pamd.muscle_type",
             "numpy",
             # it parses no YAML (commands are JSON; the config is read in the daemon)
             "pamd.wire.schema.yamlload", "yaml")


def console_script(tmp: Path) -> Path:
    """The `pamd` console script as pip writes it from the entry point."""
    scripts = (ROOT / "pyproject.toml").read_text().split("[project.scripts]", 1)[1]
    found = re.search(r'^pamd\s*=\s*"([\w.]+):(\w+)"', scripts, re.M)
    assert found, "no pamd console script in pyproject.toml"
    module, attr = found.groups()
    path = tmp / "pamd"
    path.write_text(f"import re\nimport sys\nfrom {module} import {attr}\n"
                    "if __name__ == '__main__':\n"
                    "    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])\n"
                    f"    sys.exit({attr}())\n")
    return path


def io_modules(tmp: Path, *extra: str) -> list[str]:
    out = tmp / "modules.json"
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", **{MODULES_ENV: str(out)})
    for k in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID"):
        env.pop(k, None)
    args = [sys.executable, str(console_script(tmp)), "run", "--config",
            str(ROOT / "config" / "sim.yaml"), "--clock", "virtual", "--duration", "2",
            "--record", str(tmp / "rec"), "--state-dir", str(tmp / "state"), "--json",
            "--profile", "sine", "--freq-hz", "0.2", "--max-bar", "3", *extra]
    done = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert list((tmp / "rec").glob("*.mcap")), "the run recorded nothing"
    names: list[str] = json.loads(out.read_text())
    return names


def check(names: list[str]) -> list[str]:
    pamd = [m for m in names if m == "pamd" or m.startswith("pamd.")]
    wrong = [m for m in names for f in FORBIDDEN if m == f or m.startswith(f + ".")]
    assert not wrong, f"the io process imported {wrong}"
    assert len(pamd) <= MAX_PAMD_MODULES, f"{len(pamd)} pamd modules: {pamd}"
    first = sorted({".".join(m.split(".")[:2]) for m in pamd})
    assert len(first) <= MAX_FIRST_LEVEL, f"{len(first)} first-level names: {first}"
    return pamd


def test_the_io_process_of_a_recorded_run_with_telemetry_imports_what_it_needs(
        tmp_path: Path) -> None:
    names = io_modules(tmp_path, "--listen", f"tcp/127.0.0.1:{free_port()}")
    pamd = check(names)
    # it did what it is there for: recorded, and served Zenoh with the command schemas
    for needed in ("pamd.iohost.recorder", "pamd.iohost.node", "pamd.wire.verbs.table",
                   "zenoh"):
        assert needed in names, needed
    assert "pamd.__main__" in pamd and "pamd.client.cli.main" not in pamd


def test_the_check_sees_a_forbidden_module() -> None:
    """The check itself: the loop's controller, one module too many, or one first-level
    name too many, is caught."""
    light = ["pamd", "pamd.iohost.process", "zenoh"]
    assert check(light) == ["pamd", "pamd.iohost.process"]
    for heavy in (light + ["pamd.loop.control.controller"], light + ["numpy.linalg"],
                  light + [f"pamd.x{i}" for i in range(MAX_PAMD_MODULES)],
                  light + ["pamd.__main__", "pamd.wire", "pamd.errors"]):
        try:
            check(heavy)
        except AssertionError:
            continue
        raise AssertionError(f"not caught: {heavy[3:5]}")
