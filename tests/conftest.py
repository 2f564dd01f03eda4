"""Shared fixtures: a simulated rig in one line.

`sim_config(**changes)` writes a variant of config/sim.yaml into the test's temp
dir (virtual clock, real-time off) and loads it; `harness` steps a controller tick
by tick with the virtual clock, in this thread, deterministically; `sim_daemon`
is the whole daemon (loop thread and all) on the simulated rig.
"""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# The run's own directory of rig locks (pamd.daemon.service.riglock) for what starts before a
# test's own (`rig_lock_dir`): session and module fixtures that run a daemon never meet
# a `sim` rig running on this machine, nor another checkout's test run.
_RUN_LOCK_DIR = tempfile.mkdtemp(prefix="pamd-test-locks-")
os.environ["PAMD_LOCK_DIR"] = _RUN_LOCK_DIR
# ... and of command tokens (pamd.wire.credential): every daemon the run starts writes its
# token there and every client the run starts (same environment) finds it there.
os.environ["PAMD_TOKEN_DIR"] = _RUN_LOCK_DIR
atexit.register(shutil.rmtree, _RUN_LOCK_DIR, True)
# ... and its own state home (pamd.daemon.service.state: where a real-clock run keeps its state
# by default), never the user's ~/.local/state
_RUN_STATE_HOME = tempfile.mkdtemp(prefix="pamd-test-state-")
os.environ["XDG_STATE_HOME"] = _RUN_STATE_HOME
atexit.register(shutil.rmtree, _RUN_STATE_HOME, True)


def _bytecode_for_the_processes_tests_start() -> None:
    """Where the environment turns bytecode files off (PYTHONDONTWRITEBYTECODE, as on
    the project's shared machine), every `python -m pamd` a test starts and every io
    process compiled pamd from its source again (~0.2 s of each start, a few hundred
    starts a run). This run writes them as Python does by default, in `__pycache__`
    beside the sources (git ignores them); installed packages have theirs already."""
    if os.environ.pop("PYTHONDONTWRITEBYTECODE", None):
        sys.dont_write_bytecode = False  # this process writes what it imports from here on


_bytecode_for_the_processes_tests_start()


def pytest_configure(config: pytest.Config) -> None:
    """Before any worker starts (in the run's first process only): pamd's and the
    drivers' bytecode written once, whole. Left to the processes the tests start, the
    first to import a module writes its `.pyc`, and one signalled in that write (a test
    stopping a daemon as it starts) left it cut short: CPython's writer does not check
    for a short write, and every later import of that module failed with "marshal data
    too short" until the file was deleted."""
    if hasattr(config, "workerinput") or sys.dont_write_bytecode:
        return
    import compileall

    root = Path(__file__).resolve().parents[1]
    for package in ("pamd", "drivers"):
        compileall.compile_dir(root / package, quiet=1, workers=1)

import copy  # noqa: E402
import dataclasses  # noqa: E402
import functools  # noqa: E402
import logging  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import pytest  # noqa: E402
import yaml  # noqa: E402

from pamd.client.cli.main import main  # noqa: E402
from pamd.config import LoadedConfig, load_config  # noqa: E402
from pamd.daemon.daemon import Daemon  # noqa: E402
from pamd.loop.harness import Harness  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SIM_YAML = REPO / "config" / "sim.yaml"


def merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """Deep-merge `changes` into a copy of `base` (lists are replaced)."""
    out = copy.deepcopy(base)
    for k, v in changes.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


@functools.lru_cache(maxsize=4)
def _parsed(text: str) -> dict[str, Any]:
    return yaml.safe_load(text)


def sim_dict(load_kg: float = 30.0, **changes: Any) -> dict[str, Any]:
    """config/sim.yaml as a dict, virtual clock, real-time off, with changes (the file
    is parsed once per content, each call gets its own copy)."""
    base = copy.deepcopy(_parsed(SIM_YAML.read_text()))
    base["loop"]["clock"] = "virtual"
    base["loop"]["realtime"] = {"enabled": False}
    base["telemetry"] = {"enabled": False}  # never on the default port 7447 in tests
    base["drivers"][0]["options"]["muscles"][0]["load_kg"] = load_kg
    base["muscles"][0]["load_kg"] = load_kg
    return merge(base, changes)


#: The modules that hold the suite's longest tests (a quiet run's --durations, 5-26 s a
#: test), longest first. They run first: the run ends on short tests that both workers
#: share out (--dist worksteal), not on one worker's 20 s test while the other has
#: nothing left to do (tests/view/test_live.py, last in name order, was such a tail).
LONG_FIRST = (
    "tests/e2e/test_walkthrough.py",
    "tests/models/test_adapt_e2e.py",
    "tests/test_typing.py",  # mypy: ~12 s of a core when its cache is cold
    "tests/drivers/test_daemon_emulated.py",
    "tests/view/test_live.py",
    "tests/adversary/test_net_storms.py",
    "tests/net/test_lifecycle.py",
    "tests/adversary/test_files_model.py",
    "tests/net/test_tls_acl.py",
    "tests/cli/test_collect_cli.py",
    "tests/adversary/test_files_manifest.py",
    "tests/net/test_collect_remote.py",
    "tests/service/test_notify.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """LONG_FIRST's modules first, in its order; every other test as collected. Each
    module's tests stay together and in their order (a module fixture is built once)."""
    rank = {name: i for i, name in enumerate(LONG_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.partition("::")[0], len(rank)))


def pytest_collection_finish(session: pytest.Session) -> None:
    """A test module with a `start_early(chosen)` (tests/test_typing.py: mypy) may start
    slow, self-contained work in the background as soon as the run's tests are chosen;
    `chosen` is the names of its tests in this run. Its test then waits for the result."""
    chosen: dict[Any, set[str]] = {}
    for item in session.items:
        module = getattr(item, "module", None)
        if hasattr(module, "start_early"):
            chosen.setdefault(module, set()).add(getattr(item, "originalname", item.name))
    for module, names in chosen.items():
        module.start_early(names)


@pytest.fixture(autouse=True)
def rig_lock_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Each test its own directory of rig locks (pamd.daemon.service.riglock): tests running
    at once (here or in another checkout on this machine) never share a rig's lock,
    while two daemons on one rig within a test still meet it."""
    path = tmp_path / "locks"
    monkeypatch.setenv("PAMD_LOCK_DIR", str(path))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg-state"))  # the test's own
    return path


@pytest.fixture
def sim_config(tmp_path: Path) -> Callable[..., LoadedConfig]:
    def make(load_kg: float = 30.0, **changes: Any) -> LoadedConfig:
        path = tmp_path / "sim.yaml"
        path.write_text(yaml.safe_dump(sim_dict(load_kg, **changes), sort_keys=False))
        return load_config(str(path))

    return make


@pytest.fixture
def harness(sim_config: Callable[..., LoadedConfig]) -> Iterator[Callable[..., Harness]]:
    made: list[Harness] = []

    def make(load_kg: float = 30.0, **changes: Any) -> Harness:
        h = Harness(sim_config(load_kg, **changes))
        made.append(h)
        return h

    yield make
    for h in made:
        h.rig.close()


@dataclasses.dataclass
class CliResult:
    """What a `pamd` command returned and printed (as `subprocess.run` gives it)."""

    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def pamd_here(capsys: pytest.CaptureFixture[str],
              monkeypatch: pytest.MonkeyPatch) -> Callable[..., CliResult]:
    """`pamd ARGS` through the command line's `main()` in this process, from directory
    `cwd`: for what a command answers before anything runs (a refusal, --help), where the
    Python start-up of `python -m pamd` (~0.8 s) is not what the test is about. Its log
    goes to its stderr as `main()` sets it up in a process of its own (level, format,
    the libraries' filter), so stderr reads as the process's would; an exception that
    escapes `main()` (a traceback there) fails the test. The tests of the real process
    (the interpreter's exit, signals, the daemon) start it."""

    def run(*args: str | Path, cwd: Path | None = None) -> CliResult:
        argv = [str(a) for a in args]
        if cwd is not None:
            monkeypatch.chdir(cwd)
        capsys.readouterr()
        root = logging.getLogger()
        handler = logging.StreamHandler(sys.stderr)  # capsys's stderr, as of now
        handler.setFormatter(logging.Formatter("pamd: %(message)s"))
        level = root.level
        root.addHandler(handler)
        root.setLevel(logging.DEBUG if {"-v", "--verbose"} & set(argv) else logging.INFO)
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse: --help, a usage error
            code = exc.code if isinstance(exc.code, int) else 1
        finally:
            root.removeHandler(handler)
            root.setLevel(level)
        out = capsys.readouterr()
        return CliResult(code, out.out, out.err)

    return run


@pytest.fixture
def sim_daemon(sim_config: Callable[..., LoadedConfig]) -> Iterator[Callable[..., Daemon]]:
    made: list[Daemon] = []

    def make(load_kg: float = 30.0, duration_s: float | None = None, **changes: Any) -> Daemon:
        d = Daemon(sim_config(load_kg, **changes))
        d.start(duration_s)
        made.append(d)
        return d

    yield make
    for d in made:
        d.stop("test finished")
        d.wait(timeout_s=30)
        d.close()


@pytest.fixture
def without_matplotlib(monkeypatch: pytest.MonkeyPatch) -> None:
    """`import matplotlib` raises ImportError, as without the optional `plot` extra."""
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)


# -- tools the tests drive: missing is a failure saying what to install, never a skip --
_TOOLS = {  # tool -> (Debian package, what the tests use it for)
    "socat": ("socat", "pty pairs for Modbus RTU and CAN-over-serial"),
    "systemd-analyze": ("systemd", "verifying the unit file"),
    "node": ("nodejs", "the independent MCAP reader (tests/js)"),
}


def require_tool(tool: str) -> str:
    """The tool's path; the test fails naming what to install when it is missing."""
    path = shutil.which(tool)
    if path is None:
        package, why = _TOOLS.get(tool, (tool, "these tests"))
        pytest.fail(f"{tool} is not installed ({why}): run .ci/setup-tests, or "
                    f"apt-get install {package}", pytrace=False)
    return path


@pytest.fixture
def socat() -> str:
    return require_tool("socat")


@pytest.fixture
def systemd_analyze() -> str:
    return require_tool("systemd-analyze")
