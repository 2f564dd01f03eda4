"""Where `pamd tune --save` writes the new gains: the rig's `control` section, or each
muscle's own `muscles[].control` (the same key names).

Per muscle when `--per-muscle` says so, or when the rig-wide keys would be wrong for
one of them:
- only some of the rig's muscles were tuned (`--muscle`): the others keep theirs;
- the muscles' fits differ: some gain differs from their mean by more than
  `PER_MUSCLE_SPREAD` (15 %; the fits of one muscle's steps spread by about 10 %
  between up and down steps on the simulated regulator, so less is noise);
- a tuned muscle already has its own value of one of these keys (a rig-wide value
  would not reach it).
Otherwise rig-wide, from the mean model of all the muscles' runs.
"""

from __future__ import annotations

from dataclasses import dataclass

from pamd.client.tune.tune_report import Present
from pamd.client.tune.yamledit import KeyPath
from pamd.config import LoadedConfig

PER_MUSCLE_SPREAD = 0.15


@dataclass(frozen=True)
class Placement:
    per_muscle: bool
    why: str
    values: dict[KeyPath, float]


def muscle_key(muscle: str, key: KeyPath) -> KeyPath:
    """A rig-wide control key as the same key in the muscle's own section."""
    return ("muscles", f"[{muscle}]", *key)


def place(cfg: LoadedConfig, by_muscle: dict[str, Present], rig_wide: Present,
          per_muscle: bool) -> Placement:
    """Where the new gains go, and why (see the module's docstring)."""
    tuned = list(by_muscle)
    rig_muscles = [m.name for m in cfg.rig.muscles]
    why = ""
    if per_muscle:
        why = "--per-muscle"
    elif set(tuned) != set(rig_muscles):
        why = (f"only {', '.join(tuned)} of the rig's {', '.join(rig_muscles)} were tuned; "
               "the others keep their gains")
    else:
        why = _spread(by_muscle) or _own_values(cfg, by_muscle)
    if not why:
        return Placement(False, "one muscle" if len(tuned) == 1 else
                         f"the muscles' fits agree within {PER_MUSCLE_SPREAD:.0%}",
                         rig_wide.key_values())
    values = {muscle_key(m, key): v for m, p in by_muscle.items() for key, v in p.gains.items()}
    return Placement(True, why, values)


def _spread(by_muscle: dict[str, Present]) -> str:
    if len(by_muscle) < 2:
        return ""
    first = next(iter(by_muscle.values()))
    for key in first.gains:
        if "plant" in key:  # the gains decide; each muscle's plant goes with its gains
            continue
        values = [p.gains[key] for p in by_muscle.values()]
        mean = sum(values) / len(values)
        if mean and max(abs(v - mean) for v in values) / abs(mean) > PER_MUSCLE_SPREAD:
            shown = ", ".join(f"{m} {p.gains[key]:.4g}" for m, p in by_muscle.items())
            return (f"the muscles' fits differ by more than {PER_MUSCLE_SPREAD:.0%} "
                    f"({'.'.join(key)}: {shown})")
    return ""


def _own_values(cfg: LoadedConfig, by_muscle: dict[str, Present]) -> str:
    for muscle, p in by_muscle.items():
        own = cfg.muscle(muscle).control
        for key in p.gains:
            node: object = own
            for part in key[1:]:
                node = getattr(node, part, None)
            if node is not None:
                return (f"{muscle} has its own {'.'.join(key)} in the config (a rig-wide "
                        "value would not reach it)")
    return ""
