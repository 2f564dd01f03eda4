"""What pamd says, declared once: the recorded and published fields (`fields`), the
events by name and command verdicts (`events`), the one JSON encoder (`jsonsafe`), and the
old names still served beside their new ones until a stated release (`deprecated`).

Everything else derives from these tables: the tick record's layout and indices
(`pamd.wire.tick`), the MCAP/ROS 2 message schemas (`pamd.wire.record.cdr`), the event JSON
schema (`pamd.iohost.recorder`), the exports' columns, units and descriptions
(`pamd.client.field_info`), the Foxglove layout (`pamd.client.layout`) and the generated
docs/fields-reference.md (`python -m pamd.wire.declare.fields_doc`). This package imports
nothing of pamd, so every layer may read it.
"""
