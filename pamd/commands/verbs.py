"""Every command verb with its handler: the declarations of the handler modules, by
kind (motion, rig, experiment plans), in one registry, checked against the specs the
io process parses by (`pamd.wire.verbs.table.VERBS`)."""

from __future__ import annotations

from pamd.commands import adapt, motion, plan, rig, tune
from pamd.commands.registry import VerbRegistry
from pamd.wire.verbs.table import VERBS

REGISTRY = VerbRegistry(motion.VERBS + adapt.VERBS + rig.VERBS + plan.VERBS + tune.VERBS,
                        VERBS)
