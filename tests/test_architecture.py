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

#: top to bottom, each named for what it is. A package imports only from the layers
#: below its own and, within its layer, from the packages listed after it (so there is
#: no import cycle). `net` is split by role: `net.host` (the daemon's main process),
#: `net.node` (the io process's Zenoh node), `net.client` (the client library), and
#: `net` itself, what they share (keys, specs, the board, the status's declaration).
LAYERS: list[tuple[str, list[str]]] = [
    ("command line", ["__main__", "cli", "commission", "tune"]),
    ("main process", ["daemon", "service", "io", "net.host"]),
    ("telemetry and views", ["view", "net.client", "net.node", "net"]),
    ("loop", ["harness", "loop", "commands", "experiment"]),
    ("rig tick", ["controller", "summary", "control", "safety"]),
    ("hardware, models, recordings",
     ["rig", "emulate", "drivers", "models", "record", "sim", "rt", "stalls", "calibration"]),
    ("verbs and config", ["verbs", "config", "schema", "plugins"]),
    ("leaves", ["ipc", "metrics", "timing", "muscle_type", "tick", "profiles", "profile_kinds",
                "atomic", "errors", "version", "declare", "data"]),
]
MAX_LAYERS = 10

#: the subpackages placed in LAYERS on their own
SUBPACKAGES = {"net.node", "net.host", "net.client"}

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
    "pamd/client/cli/main.py": "pamd.client.cli.",
    # a custom muscle's map is read by the reader `pamd train` uses (pamd.client.training_tables, a
    # layer above the config), only when a config names one
    "pamd/config/muscle_types.py": "pamd.client.training_tables",
}


def _sources() -> Iterator[tuple[str, Path]]:
    for base, prefix in (("pamd", "pamd"), ("drivers", "pamd.drivers")):
        for path in sorted((ROOT / base).rglob("*.py")):
            rel = path.relative_to(ROOT / base).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            yield ".".join([prefix, *parts]), path


def _package(module: str) -> str | None:
    parts = module.split(".")
    if len(parts) > 2 and parts[0] == "pamd" and ".".join(parts[1:3]) in SUBPACKAGES:
        return ".".join(parts[1:3])
    return parts[1] if len(parts) > 1 and parts[0] == "pamd" else None


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
    assert not [t for t, _, _ in _imports("pamd.client.cli.main", main) if t.startswith(prefix)]


def test_the_check_sees_an_upward_and_a_lazy_import(tmp_path: Path) -> None:
    """The check itself: an import of a higher layer, and one inside a function."""
    probe = tmp_path / "probe.py"
    probe.write_text("from pamd.loop.control.pid import Pid\ndef f():\n    import pamd.daemon.daemon\n")
    found = list(_imports("pamd.config.probe", probe))
    assert ("pamd.loop.control.pid", 1, False) in found
    assert ("pamd.daemon.daemon", 3, True) in found
    layer = _layer_of()
    assert layer["control"] < layer["config"] and layer["daemon"] < layer["config"]
    assert _package("pamd.iohost.intake") == "net.node" and _package("pamd.wire.keys") == "net"
    assert layer["net.node"] < layer["net"] and layer["io"] < layer["net.node"]


def test_every_package_of_the_tree_is_installed() -> None:
    """`pip install .` ships the packages pyproject lists: a new package left out of the
    list imports from the clone and fails from an installed pamd (tests/test_install.py
    finds it too, slowly)."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    tree = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "pamd").rglob(
        "__init__.py") if "__pycache__" not in p.parts}
    assert tree <= listed, f"not in pyproject's packages: {sorted(tree - listed)}"
