"""Write new values (gains, thresholds, a muscle's type) into a config file in place,
after showing the diff, keeping its comments and layout (`pamd.client.tune.yamledit`); the
edited text must still load as a valid config. Where the file cannot be edited safely,
the values go to an overrides file beside it (CONFIG.tuned.yaml) and it says so. Files
the new values name (a measured map) are written beside the config first, the same
way. `pamd tune --save` and `pamd commission --save` both write this way."""

from __future__ import annotations

import difflib
import os
import sys
from collections.abc import Mapping

import yaml

from pamd.client.tune.yamledit import KeyPath, Value, YamlEditError, parsed_value, set_values
from pamd.config.loader import load_config_text
from pamd.wire.atomic import write_atomic
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ConfigError


def save_values(config_path: str, values: Mapping[KeyPath, Value], what: str = "gains",
                tool: str = "pamd tune", label: str = "tuned",
                files: dict[str, str] | None = None) -> int:
    """Write `values` into the config file (or the overrides file); 0. `what` the
    values say in messages, `tool` who wrote them, `label` the diff's new side; `files`
    (path -> text) are written first: what the values name (the edited config must
    load with them)."""
    for path, content in (files or {}).items():
        write_atomic(path, content)  # whole or not at all: FileWriteError names it
        print(f"wrote {path}")
    with open(config_path, encoding="utf-8") as fh:
        text = fh.read()
    try:
        edited = set_values(text, values)
        check_loads(edited, config_path)
    except YamlEditError as exc:
        return write_overrides(config_path, values, str(exc), what, tool)
    sys.stdout.writelines(difflib.unified_diff(
        text.splitlines(keepends=True), edited.splitlines(keepends=True),
        fromfile=config_path, tofile=f"{config_path} ({label})"))
    write_atomic(config_path, edited)  # whole or not at all: FileWriteError names it
    print(f"saved the new {what} into {config_path}")
    return 0


def check_loads(text: str, path: str) -> None:
    """The edited config must still be a valid config."""
    try:
        load_config_text(text, path)
    except ConfigError as exc:
        raise YamlEditError(f"the edited config would not load: {exc}") from None


def write_overrides(config_path: str, values: Mapping[KeyPath, Value], why: str,
                    what: str = "gains", tool: str = "pamd tune") -> int:
    root, _ = os.path.splitext(config_path)
    path = root + ".tuned.yaml"
    nested: JsonObject = {}  # the YAML written
    items: dict[str, JsonObject] = {}  # muscles[] items by name
    for key_path, value in values.items():
        node = nested
        keys = key_path
        if key_path[0] == "muscles":  # ("muscles", "[m1]", ...): that muscle's item
            name = key_path[1][1:-1]
            if name not in items:
                items[name] = {"name": name}
                nested.setdefault("muscles", []).append(items[name])
            node, keys = items[name], key_path[2:]
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        node[keys[-1]] = parsed_value(value)
    write_atomic(path, f"# {tool}: {what} for {os.path.basename(config_path)}, which could "
                 f"not be edited in place\n# ({why}). Merge these keys into it.\n"
                 + yaml.safe_dump(nested, sort_keys=False))
    print(f"{config_path} could not be edited in place ({why}); the new {what} are in "
          f"{path}: merge them into the config")
    return 0
