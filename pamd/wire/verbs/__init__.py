"""The command language: what a client may send, with no loop state.

- `schema`: each verb's argument dataclass, the `Command` on its way to the loop, the
  caps on text.
- `table`: every public verb declared once (`VERBS`: name, arguments, routing, help),
  and `parse_command`: a payload's shape checked by its verb's spec (unknown fields,
  types, NaN).

The io process parses, validates and routes by these alone; the loop's handlers are in
`pamd.loop.commands`, declared against these specs by name.
"""
