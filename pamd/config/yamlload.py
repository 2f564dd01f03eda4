"""YAML loading that remembers where every key came from.

Mappings load as `LinedDict`: a dict that also knows its own line and the line of
each key, so validation errors can name the line an operator has to edit.
"""

from __future__ import annotations

from typing import Any

import yaml

from pamd.errors import ConfigError, ConfigIssue


class LinedDict(dict):
    """A mapping from YAML with `line` (its own) and `key_lines` (per key), 1-based."""

    line: int | None = None
    key_lines: dict[str, int]


class LinedList(list):
    """A sequence from YAML with `line` and `item_lines`, 1-based."""

    line: int | None = None
    item_lines: list[int]


class _Loader(yaml.SafeLoader):
    pass


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LinedDict:
    loader.flatten_mapping(node)
    out = LinedDict()
    out.line = node.start_mark.line + 1
    out.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in out.key_lines:
            raise ConfigError(
                [
                    ConfigIssue(
                        loader.name, key_node.start_mark.line + 1, str(key), "each key once",
                        "a duplicate key",
                    )
                ]
            )
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_lines[key] = key_node.start_mark.line + 1
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LinedList:
    out = LinedList(loader.construct_object(child, deep=True) for child in node.value)
    out.line = node.start_mark.line + 1
    out.item_lines = [child.start_mark.line + 1 for child in node.value]
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_yaml_text(text: str, file: str) -> Any:
    """Parse YAML text; a syntax error becomes a ConfigError with the line."""
    loader = _Loader(text)
    loader.name = file
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else None
        raise ConfigError(
            [ConfigIssue(file, line, "", "valid YAML", f"{exc.problem or exc}")]
        ) from None
    finally:
        loader.dispose()


def read_text(path: str, what: str = "a readable YAML file") -> str:
    """A file's text; a missing or unreadable file is a ConfigError saying why."""
    try:
        with open(path, encoding="utf-8") as fh:
            return fh.read()
    except OSError as exc:
        raise ConfigError([ConfigIssue(path, None, "", what, exc.strerror or str(exc))]) from None


def load_yaml_file(path: str) -> Any:
    """Read and parse a YAML file; a missing or unreadable file is a ConfigError."""
    return load_yaml_text(read_text(path), path)
