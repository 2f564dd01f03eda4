"""The package layers (docs/architecture.md draws them), checked on the source.

A module may import only from its own package, from a layer below its own, or from a
package listed after its own in its layer. So there is no import cycle between
packages. An import inside a function is allowed only for an
optional or heavy third-party dependency (plots, training, the network stacks), never
to dodge a cycle. `drivers/` installs as `pamd.drivers`, which is why this test reads
the source rather than using import-linter (it cannot see a package mapped from
another directory).
"""

from __future__ import annotations

import ast
import functools
import sys
from collections.abc import Iterator
from pathlib import Path

import tomllib  # tests run on Python >= 3.11

ROOT = Path(__file__).resolve().parents[1]

#: top to bottom, each named for what it is: the processes, each its own package (the
#: client side, the main process, the loop process, the io process), the libraries,
#: and at the bottom what crosses between the processes (`wire`). A package imports
#: only from the layers below its own and, within its layer, from the packages listed
#: after it (so there is no import cycle). A process package's subpackages that form
#: layers of their own are placed on their own (`loop.control` under `loop.commands`).
LAYERS: list[tuple[str, list[str]]] = [
    ("client", ["__main__", "_moved", "client.cli", "client.commission", "client.tune",
                "client"]),
    ("main process", ["daemon", "daemon.service", "daemon.host"]),
    ("loop process", ["loop", "loop.commands", "loop.experiment", "loop.control",
                      "loop.safety", "loop.devices"]),
    ("io process", ["iohost"]),
    ("libraries", ["emulate", "drivers", "sim", "models", "config", "profiles",
                   "muscle_type", "data"]),
    ("wire", ["wire"]),
]
MAX_LAYERS = 10

#: the process packages (issue 41): each process's code in one, and what crosses a
#: process boundary in one (`wire`); no module base name twice in one of them
PROCESS_PACKAGES = {"client": "the Python API, recordings, the command line",
                    "daemon": "the main process", "loop": "the loop process",
                    "iohost": "the io process", "wire": "what crosses between them"}
#: at most this many modules at pamd/'s root (`__init__`, `__main__` included; 19
#: before issue 41)
MAX_ROOT_MODULES = 6
#: at most this many module base names found more than once in pamd/ (27 before
#: issue 41): a name that recurs says less than it should
MAX_RECURRING_NAMES = 10

#: third-party packages a function may import when it needs them (heavy, or optional
#: extras, or only one command uses them): keeps `import pamd` and the daemon light
LAZY_THIRD_PARTY = {
    "matplotlib", "scipy", "pandas", "sklearn", "zenoh", "foxglove", "canopen", "can",
    "serial", "pymodbus", "tqdm", "zstandard", "lz4", "nidaqmx", "grpc", "session_pb2",
}

#: pamd's own lazy imports beyond the heavy modules: the public API
#: (`pamd.open_recording`, `pamd.connect`) on first use, so that `import pamd` does not
#: pull the readers into the daemon and its io process
LAZY_OWN = {
    "pamd/__init__.py": "pamd.",
    # the console script's module: a spawned process (the io process) runs it again
    "pamd/__main__.py": "pamd.client.cli.main",
    # the io process imports the Foxglove live view only for a run that asks for it
    "pamd/iohost/process.py": "pamd.iohost.live",
    # the io process checks tokens with this module; only the daemon writes one
    "pamd/wire/credential.py": "pamd.wire.atomic",
}

#: the modules that import by name (`importlib.import_module`), which the checks
#: above cannot read, and the modules each may name: the public API's lazy names, and
#: the command line's sub-commands (pamd.client.cli.main.COMMANDS), each imported only when
#: chosen so that `pamd --help` and `pamd status` do not import the daemon
LAZY_BY_NAME = {
    "pamd/__init__.py": "pamd.",
    # the module names before issue 41's move, each imported as the module it names now
    "pamd/_moved.py": "pamd.",
    "pamd/client/cli/main.py": "pamd.client.cli.",
    # a custom muscle's map is read by the reader `pamd train` uses
    # (pamd.client.training_tables, a layer above the config), only when a config names one
    "pamd/config/muscle_types.py": "pamd.client.training_tables",
}


def _sources() -> Iterator[tuple[str, Path]]:
    for base, prefix in (("pamd", "pamd"), ("drivers", "pamd.drivers")):
        for path in sorted((ROOT / base).rglob("*.py")):
            rel = path.relative_to(ROOT / base).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            yield ".".join([prefix, *parts]), path


@functools.cache
def _placed() -> frozenset[str]:
    return frozenset(n for _, layer in LAYERS for n in layer)


def _package(module: str) -> str | None:
    """The longest package placed in LAYERS that holds the module (its first-level
    package when none is: `test_every_package_has_a_layer` names it)."""
    parts = module.split(".")
    if len(parts) < 2 or parts[0] != "pamd":
        return None
    for k in range(len(parts) - 1, 1, -1):
        if ".".join(parts[1:k + 1]) in _placed():
            return ".".join(parts[1:k + 1])
    return parts[1]


def _imports(module: str, path: Path) -> Iterator[tuple[str, int, bool]]:
    """(imported module, line, inside a function) for every import of the file."""
    yield from _parsed_imports(module, path)


@functools.cache
def _parsed_imports(module: str, path: Path) -> list[tuple[str, int, bool]]:
    """`_imports`, each file parsed once per run (the tests below read every file)."""
    return list(_parse_imports(module, path))


def _parse_imports(module: str, path: Path) -> Iterator[tuple[str, int, bool]]:
    tree = ast.parse(path.read_text(), str(path))
    in_function: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            in_function.update(id(n) for n in ast.walk(node) if n is not node)
    is_package = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno, id(node) in in_function
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                base = base[: len(base) - node.level + (1 if is_package else 0)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            yield target, node.lineno, id(node) in in_function


def _layer_of() -> dict[str, int]:
    """Each package's rank, top to bottom (layer by layer, and in its layer's order)."""
    return {name: i for i, name in enumerate(n for _, layer in LAYERS for n in layer)}


def _layer_index() -> dict[str, int]:
    return {name: i for i, (_, layer) in enumerate(LAYERS) for name in layer}


def test_the_layers_are_few_and_named() -> None:
    assert len(LAYERS) <= MAX_LAYERS
    names = [name for name, _ in LAYERS]
    assert len(set(names)) == len(names) and all(names)
    placed = [p for _, layer in LAYERS for p in layer]
    assert len(set(placed)) == len(placed), "a package placed twice"
    doc = (ROOT / "docs" / "architecture.md").read_text()
    missing = [n for n in names if f"| {n} |" not in doc]
    assert not missing, f"docs/architecture.md does not name these layers: {missing}"


def test_every_package_has_a_layer() -> None:
    layer = _layer_of()
    missing = sorted({p for m, _ in _sources() if (p := _package(m)) and p not in layer})
    assert not missing, f"place these in LAYERS (and docs/architecture.md): {missing}"


def test_imports_go_down_the_layers_only() -> None:
    layer = _layer_of()
    wrong = []
    for module, path in _sources():
        own = _package(module)
        for target, line, _ in _imports(module, path):
            theirs = _package(target)
            if own is None or theirs is None or theirs == own or own == "__init__":
                continue
            if layer[theirs] <= layer[own]:
                where = ("a package before it in its layer"
                         if _layer_index()[theirs] == _layer_index()[own] else "a higher layer")
                wrong.append(f"{path.relative_to(ROOT)}:{line}: pamd.{own} imports "
                             f"{target} ({where})")
    assert not wrong, "\n".join(wrong)


def _heavy_modules() -> set[str]:
    """pamd's modules that pull a lazy third-party package when imported (directly or
    through another such module): a function may import these on first use."""
    pulls: dict[str, set[str]] = {}
    for module, path in _sources():
        pulls[module] = {t for t, _, inside in _imports(module, path) if not inside}
    heavy = {m for m, ts in pulls.items()
             if any(t.split(".")[0] in LAZY_THIRD_PARTY for t in ts)}
    grew = True
    while grew:
        more = {m for m, ts in pulls.items() if m not in heavy and ts & heavy}
        heavy |= more
        grew = bool(more)
    return heavy


def test_no_import_hides_in_a_function() -> None:
    stdlib = set(sys.stdlib_module_names)
    heavy = _heavy_modules()
    wrong = []
    for module, path in _sources():
        rel = str(path.relative_to(ROOT))
        for target, line, inside in _imports(module, path):
            if not inside:
                continue
            top = target.split(".")[0]
            if top in LAZY_THIRD_PARTY:
                continue
            if top == "pamd" and (target in heavy or target.startswith(LAZY_OWN.get(rel, "\0"))):
                continue
            kind = "the standard library" if top in stdlib else "pamd" if top == "pamd" else top
            wrong.append(f"{rel}:{line}: {target} ({kind}) imported inside a function")
    assert not wrong, "\n".join(wrong)


def test_only_the_named_modules_import_by_name() -> None:
    wrong = []
    for _, path in _sources():
        rel = str(path.relative_to(ROOT))
        if rel in LAZY_BY_NAME:
            continue
        for node in ast.walk(ast.parse(path.read_text(), rel)):
            if (isinstance(node, ast.Attribute) and node.attr == "import_module"
                    or isinstance(node, ast.Name) and node.id == "__import__"):
                wrong.append(f"{rel}:{node.lineno}: imports by name")
    assert not wrong, "\n".join(wrong)


def test_the_cli_imports_only_its_own_subcommands_by_name() -> None:
    """pamd.client.cli.main imports a sub-command's module by its declared name: each one a
    module of pamd.client.cli (so the layers hold), and none imported at the top."""
    from pamd.client.cli.main import COMMANDS

    prefix = LAZY_BY_NAME["pamd/client/cli/main.py"]
    for command in COMMANDS:
        assert command.module.startswith(prefix), command
        assert (ROOT / (command.module.replace(".", "/") + ".py")).is_file(), command
    main = ROOT / "pamd" / "client" / "cli" / "main.py"
    assert not [t for t, _, _ in _imports("pamd.client.cli.main", main)
                if t.startswith(prefix)]


def test_the_check_sees_an_upward_and_a_lazy_import(tmp_path: Path) -> None:
    """The check itself: an import of a higher layer, and one inside a function."""
    probe = tmp_path / "probe.py"
    probe.write_text("from pamd.loop.control.pid import Pid\ndef f():\n"
                     "    import pamd.daemon.daemon\n")
    found = list(_imports("pamd.config.probe", probe))
    assert ("pamd.loop.control.pid", 1, False) in found
    assert ("pamd.daemon.daemon", 3, True) in found
    layer = _layer_of()
    assert layer["loop.control"] < layer["config"] and layer["daemon"] < layer["config"]
    assert _package("pamd.loop.control.pid") == "loop.control"
    assert _package("pamd.loop.loop") == "loop" and _package("pamd.wire.declare.fields") == "wire"
    assert layer["loop.commands"] < layer["loop.control"] < layer["wire"]


def test_every_package_of_the_tree_is_installed() -> None:
    """`pip install .` ships the packages pyproject lists: a new package left out of the
    list imports from the clone and fails from an installed pamd (tests/test_install.py
    finds it too, slowly)."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    tree = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "pamd").rglob(
        "__init__.py") if "__pycache__" not in p.parts}
    assert tree <= listed, f"not in pyproject's packages: {sorted(tree - listed)}"


def _modules() -> list[Path]:
    return [p for p in sorted((ROOT / "pamd").rglob("*.py")) if "__pycache__" not in p.parts]


def test_the_tree_shows_the_processes() -> None:
    """Issue 41: each process package is there and placed; few modules at pamd/'s root;
    few base names recur, and none twice in one process package (`pamd/loop/` holds one
    `plan.py` at most: the experiment's, not the verbs')."""
    placed = {n.split(".")[0] for n in _placed()}
    for name in PROCESS_PACKAGES:
        assert (ROOT / "pamd" / name / "__init__.py").is_file() and name in placed, name
    root = [p.name for p in (ROOT / "pamd").glob("*.py")]
    assert len(root) <= MAX_ROOT_MODULES, f"{len(root)} modules at pamd/'s root: {root}"
    where: dict[str, list[str]] = {}
    for path in _modules():
        if path.name != "__init__.py":
            where.setdefault(path.name, []).append(str(path.relative_to(ROOT)))
    recurring = {name: paths for name, paths in where.items() if len(paths) > 1}
    assert len(recurring) <= MAX_RECURRING_NAMES, f"{len(recurring)} recur: {recurring}"
    twice = {name: paths for name, paths in recurring.items() for process in PROCESS_PACKAGES
             if sum(p.startswith(f"pamd/{process}/") for p in paths) > 1}
    assert not twice, f"a base name twice in one process package: {twice}"
