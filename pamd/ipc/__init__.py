"""Inter-process channels between the loop process and the io process: one shared
memory block holding a control header and three single-producer single-consumer
rings (tick records, events, commands)."""
