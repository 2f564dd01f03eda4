"""`pip install .` (the README's first command, not editable), then pamd works from
anywhere: from the clone's own root too, where the clone's `pamd/` comes first on the
import path and has no `drivers/` (they sit at the top level and install as
pamd.drivers). A copy of this checkout is installed into a venv of its own
(--system-site-packages for the dependencies, --no-deps and --no-build-isolation: no
network) and run from its root and from elsewhere."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

from tests.cli.test_first_run import in_a_terminal

REPO = Path(__file__).resolve().parents[1]


def _clone(dest: Path) -> None:
    """The checkout's files as git knows them (committed or not, new ones too), without
    what a build or a test run left behind: as a fresh clone has them."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=REPO,
        capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        src = REPO / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(the clone, its venv's python) after `pip install .` of the clone."""
    root = tmp_path_factory.mktemp("install")
    clone, env = root / "pamd", root / "venv"
    _clone(clone)
    venv.create(env, system_site_packages=True, with_pip=False)
    python = env / "bin" / "python"
    # what this interpreter has (the test extra's setuptools, the dependencies) when it
    # is a venv itself: its site-packages as a plain path (its .pth files, such as an
    # editable pamd's, are not run), after the new venv's own
    own = sysconfig.get_paths()["purelib"]
    new = subprocess.run([str(python), "-c", "import sysconfig; "
                          "print(sysconfig.get_paths()['purelib'])"], capture_output=True,
                         text=True, check=True).stdout.strip()
    Path(new).mkdir(parents=True, exist_ok=True)
    (Path(new) / "_outer_site.pth").write_text(own + "\n")
    r = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-deps",
         "--no-build-isolation", "--no-index", "."], cwd=clone, capture_output=True,
        text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    return clone, python


def _run(python: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run([str(python), *args], cwd=cwd, capture_output=True, text=True,
                          env=env, timeout=300)


def test_python_m_pamd_runs_from_the_clones_root(installed: tuple[Path, Path]) -> None:
    clone, python = installed
    r = _run(python, clone, "-m", "pamd", "--help")
    assert r.returncode == 0, r.stderr
    assert "usage: pamd" in r.stdout and "Traceback" not in r.stderr
    # the clone's pamd (first on the path) with the clone's drivers, and every driver's
    # entry point loads from there
    r = _run(python, clone, "-c", "import pamd, pamd.drivers.sim, pamd.drivers.modbus; "
             "from pamd.drivers import available_drivers as a; "
             "[e.load() for e in a().values()]; "
             "print(pamd.__file__); print(pamd.drivers.sim.__file__)")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(clone / "pamd" / "__init__.py"),
                                str(clone / "drivers" / "sim.py")]
    r = _run(python, clone, "-m", "pamd", "check-config", "config/rig.yaml")
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_installed_package_runs_from_elsewhere(installed: tuple[Path, Path],
                                                   tmp_path: Path) -> None:
    clone, python = installed
    r = _run(python, tmp_path, "-c", "import pamd, pamd.drivers.sim as s; "
             "print(pamd.__file__); print(s.__file__)")
    assert r.returncode == 0, r.stderr
    files = r.stdout.split()
    assert all("site-packages" in f for f in files), files  # not the clone's
    assert files[1].endswith(os.path.join("pamd", "drivers", "sim.py"))
    r = _run(python, tmp_path, "-m", "pamd", "--help")
    assert r.returncode == 0 and "usage: pamd" in r.stdout, r.stderr


def test_the_readmes_first_command_records_in_a_terminal(installed: tuple[Path, Path],
                                                         tmp_path: Path) -> None:
    """`pamd run --duration 10 --profile sine` (here 2 s, and without telemetry: the
    machine may have a daemon on the default port), as the installed console script,
    in a terminal: it records into ./runs and says what to do with the file."""
    _clone_root, python = installed
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    code, out = in_a_terminal(["run", "--duration", "2", "--profile", "sine",
                               "--no-telemetry"], tmp_path, pamd=(str(python.parent / "pamd"),),
                              env=env)
    assert code == 0, out
    files = list((tmp_path / "runs").glob("*.mcap"))
    assert len(files) == 1, out
    assert f"next: pamd inspect runs/{files[0].name}" in out


def test_a_bench_script_imports_pamd_from_the_clone(installed: tuple[Path, Path]) -> None:
    """A benchmark starts `python -m pamd` in the clone's root (bench/collect_sweep.py):
    as in the test above; and imports pamd with bench/ first on its path, the
    installed package."""
    clone, python = installed
    r = _run(python, clone, "-c", "import runpy, sys; sys.path.insert(0, 'bench'); "
             "import _common, pamd.drivers.sim; print('ok')")
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr
