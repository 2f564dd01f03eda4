"""The row every seed's comparison prints: the paper's figure beside pamd's (issue 29
item 4). `bench/seeds.py` collects the rows of `bench/seedNNN.py` (one module per seed,
000-004, each with `rows(quick: bool) -> list[SeedRow]`) and prints one table; the
docs carry it (docs/explanation/seeds.md).

A row compares one figure measured on the paper's protocol as closely as the simulated
rig allows. `like_for_like` says "yes" only where protocol, signal and metric are the
paper's; otherwise it says what differs (a simulated DMSP-20 for the paper's own muscle,
another load range, ...), so nobody reads a row as more than it is.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SeedRow:
    """One compared figure of one seed."""

    seed: str           # "000".."004" (the glossary in docs/architecture.md names the papers)
    figure: str         # what is compared, e.g. "max deviation, unseen 50 kg, MGA"
    paper: str          # the paper's figure as printed, with its unit, e.g. "1.2 %"
    pamd: str           # pamd's measured figure, with its unit
    like_for_like: str  # "yes", or what differs from the paper's protocol


def markdown(rows: list[SeedRow]) -> str:
    """The rows as one Markdown table (docs/explanation/seeds.md's form)."""
    lines = ["| seed | figure | paper | pamd | like for like |",
             "|---|---|---|---|---|"]
    lines += [f"| {r.seed} | {r.figure} | {r.paper} | {r.pamd} | {r.like_for_like} |"
              for r in rows]
    return "\n".join(lines)
