"""Every command verb with its handler: the declarations of the handler modules, by
group (motion, rig, experiment plans, tune, adapt), in one registry, checked against the specs the
io process parses by (`pamd.wire.verbs.table.VERBS`)."""

from __future__ import annotations

from pamd.loop.commands import (
    adapt_verbs as adapt,
)
from pamd.loop.commands import (
    motion_verbs as motion,
)
from pamd.loop.commands import (
    plan_verbs as plan,
)
from pamd.loop.commands import (
    rig_verbs as rig,
)
from pamd.loop.commands import (
    tune_verbs as tune,
)
from pamd.loop.commands.verb_registry import VerbRegistry
from pamd.wire.verbs.table import VERBS

REGISTRY = VerbRegistry(motion.VERBS + adapt.VERBS + rig.VERBS + plan.VERBS + tune.VERBS,
                        VERBS)
