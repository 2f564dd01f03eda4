"""Every command verb: the declarations of the handler modules, by kind (motion, rig,
experiment plans), in one registry."""

from __future__ import annotations

from pamd.commands import adapt, motion, plan, rig, tune
from pamd.commands.registry import VerbRegistry

REGISTRY = VerbRegistry(motion.VERBS + adapt.VERBS + rig.VERBS + plan.VERBS + tune.VERBS)
