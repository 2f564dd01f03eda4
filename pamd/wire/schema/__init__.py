"""The schema leaf: YAML read with line numbers (`yamlload`) and the engine that turns
a mapping into a frozen dataclass with file:line:key errors (`engine`: `spec`,
`build_dataclass`, `Context`). It imports nothing of pamd but `pamd.wire.errors`, so the
config, the drivers' options, plans and commands all build on it without a cycle."""
