"""The io process's Zenoh node (`node.NetNode`): the session, its publishers and
queryables, polled from the io process's one thread; remote commands checked
(`urgent`, `ranges`, `refusals`) before the command mailbox; the `status` answer
with the loop's timing from the drained records (`answer`). Never imported by
the daemon's main process or the loop's."""
