"""The row every seed's comparison prints: the paper's figure beside pamd's (issue 29
item 4), under a named protocol (issue 46 item 1). `bench/seeds.py` collects the rows
of `bench/seedNNN.py` (one module per seed, 000-004, each with `rows(quick: bool, data:
str | None = None) -> list[SeedRow]`) and prints two tables; the docs carry them
(docs/explanation/seeds.md).

A row compares one figure. `protocol` says under whose protocol it was measured:
`PAPER`, the paper's own (its split, its metric basis, its per-condition fits, its
settings where pamd has them), or `PAMD`, pamd's stricter one (loads never trained on,
held-out curves, settings chosen on validation data). `like_for_like` says "yes" only
where protocol, signal and metric are the paper's; otherwise it says what differs (a
simulated DMSP-20 for the paper's own muscle, another load range, ...), so nobody reads
a row as more than it is.
"""

from __future__ import annotations

from dataclasses import dataclass

PAPER = "paper"  # the paper's protocol
PAMD = "pamd"  # pamd's stricter protocol
PROTOCOL_TITLES = {
    PAPER: "The papers' protocols (each paper's split, metric basis and per-condition "
           "fits)",
    PAMD: "pamd's protocols (loads never trained on, held-out curves, settings chosen on "
          "validation data)",
}


@dataclass(frozen=True)
class SeedRow:
    """One compared figure of one seed."""

    seed: str           # "000".."004" (the glossary in docs/architecture.md names the papers)
    figure: str         # what is compared, e.g. "max deviation, unseen 50 kg, MGA"
    paper: str          # the paper's figure as printed, with its unit, e.g. "1.2 %"
    pamd: str           # pamd's measured figure, with its unit
    like_for_like: str  # "yes", or what differs from the paper's protocol
    protocol: str = PAMD  # PAPER or PAMD: under whose protocol pamd's figure was measured


def markdown(rows: list[SeedRow]) -> str:
    """The rows as Markdown: one table per protocol, the paper's first, each titled."""
    out: list[str] = []
    for protocol in (PAPER, PAMD):
        mine = [r for r in rows if r.protocol == protocol]
        if not mine:
            continue
        if out:
            out.append("")
        out += [f"**{PROTOCOL_TITLES[protocol]}**", "",
                "| seed | figure | paper | pamd | like for like |", "|---|---|---|---|---|"]
        out += [f"| {r.seed} | {r.figure} | {r.paper} | {r.pamd} | {r.like_for_like} |"
                for r in mine]
    return "\n".join(out)
