"""MATLAB's FIS files in and out: a pamd Sugeno model (kind anfis or ts-fuzzy) as the
`.fis` text that the Fuzzy Logic Toolbox's `readfis` reads (`export_fis`), and a
Sugeno `.fis` (seeds 000 and 001 were done in that toolbox) as a pamd model file that
`pamd evaluate` judges and `pamd run --model` runs as feedforward (`import_fis`).

The file (version 3.0; 1.0 and 2.0 read alike): sections in this order,

    [System]   Name='..' Type='sugeno' Version=3.0 NumInputs=d NumOutputs=1 NumRules=R
               AndMethod='prod' OrMethod='probor' ImpMethod='prod' AggMethod='sum'
               DefuzzMethod='wtaver'
    [Input1] .. [Inputd]   Name='force_n' Range=[lo hi] NumMFs=m
               MF1='in1mf1':'gaussmf',[sigma c]      (or 'gbellmf',[a b c])
    [Output1]  Name='pressure_bar' Range=[lo hi] NumMFs=K
               MF1='out1mf1':'linear',[p1 .. pd q]   (or 'constant',[q])
    [Rules]    one line a rule: "i1 .. id, o (weight) : connection" (1-based MF
               numbers of each input, the output MF, the weight, 1 AND / 2 OR)

Lines starting with % or # and blank lines are skipped (as readfis does); strings may
be quoted ' or ".

What it means (MATLAB's evalfis for a Sugeno system): gaussmf(x) = exp(-(x - c)^2 /
(2 sigma^2)); gbellmf(x) = 1 / (1 + |(x - c) / a|^(2b)); a rule fires with the
product of its MFs (AndMethod prod) times its weight; the output is the
firing-weighted average (DefuzzMethod wtaver) of the rules' outputs, linear
p . x + q or constant q, in the inputs' and output's own units.

pamd's model is the same structure on scaled inputs s = (x - offset) / span (see
`pamd.models.anfis.model`): a Gaussian in s is a Gaussian in x with centre
offset + span c and width span sigma, a bell likewise (a and c scale, b stays), and a
linear consequent sum p_i s_i + q is linear in x with p_i / span_i and
q - sum p_i offset_i / span_i. Export does this algebra, and import its inverse with
minmax scaling over each input's Range: the exported and imported models predict
alike to float rounding (about 1e-15 relative). Values are in the signals' own units
(force N, length mm, pressure bar, ...), stated on import.

What pamd's model cannot hold is refused naming the section and line: a Mamdani (or
any non-Sugeno) system, an MF type other than gaussmf/gbellmf (or both in one file:
pamd's model has one MF shape), an output MF other than linear/constant, rules that
name an MF an input does not have, rules that leave out an input or negate one (0,
-k), OR rules, unequal rule weights, rules that are not one for every combination of
the inputs' MFs (pamd's grid), another AndMethod than prod or DefuzzMethod than
wtaver, and inputs or outputs that are not pamd signals (`--inputs`/`--output` name
them). Outside a model's ranges pamd holds the inputs to them (as it does for every
model); MATLAB's evalfis does not clip.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pamd.models.anfis.model import AnfisModel
from pamd.models.contract import InverseModel, Variable
from pamd.models.data.extraction import derived_inputs
from pamd.models.data.samples import INPUT_UNITS, OUTPUT_UNITS
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.wire.atomic import write_atomic
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError
from pamd.wire.version import __version__

#: The version written (readfis reads 1.0, 2.0 and 3.0 alike for a type-1 system).
VERSION = "3.0"
#: pamd's MF shape for each MATLAB input MF type, and its parameters' order there.
INPUT_MFS: dict[str, tuple[str, tuple[str, ...]]] = {
    "gaussmf": ("gaussian", ("sigma", "c")),
    "gbellmf": ("bell", ("a", "b", "c")),
}
MATLAB_MF = {shape: name for name, (shape, _) in INPUT_MFS.items()}
OUTPUT_MFS = ("linear", "constant")
#: The kinds stored as a Sugeno FIS (the `AnfisModel` structure)
KINDS = ("anfis", "ts-fuzzy")
#: Largest .fis read (bytes): a 125-rule, 3-input model is about 12 kB.
MAX_FILE_BYTES = 4 * 1024 * 1024


class FisError(ModelError):
    """A .fis file pamd cannot read or hold (names the file, line and section)."""


# -- the file's structure ---------------------------------------------------------------
@dataclass(frozen=True)
class FisMf:
    """One membership function line: MFk='name':'type',[params]."""

    index: int
    name: str
    type: str
    params: tuple[float, ...]
    line: int


@dataclass(frozen=True)
class FisVar:
    """An [InputN] or [OutputN] section."""

    section: str
    line: int  # of its header
    name: str
    name_line: int
    range: tuple[float, float]
    range_line: int
    mfs: tuple[FisMf, ...]


@dataclass(frozen=True)
class FisRule:
    """One line of [Rules]: 1-based MF numbers of each input, the output MF, weight,
    connection (1 AND, 2 OR)."""

    antecedent: tuple[float, ...]
    consequent: float
    weight: float
    connection: int
    line: int


@dataclass(frozen=True)
class Fis:
    """A parsed .fis file (any type: `to_model` refuses what pamd cannot hold)."""

    source: str
    system: dict[str, tuple[str, int]]  # key -> (value, line)
    system_line: int
    inputs: tuple[FisVar, ...]
    outputs: tuple[FisVar, ...]
    rules: tuple[FisRule, ...]
    rules_line: int

    def value(self, key: str) -> str:
        if key not in self.system:
            raise self.error(self.system_line, "System", f"no {key}= line")
        return self.system[key][0]

    def line_of(self, key: str) -> int:
        return self.system.get(key, ("", self.system_line))[1]

    def error(self, line: int, section: str, message: str) -> FisError:
        return FisError(f"{self.source}:{line}: [{section}] {message}")


@dataclass
class _Section:
    name: str
    line: int
    entries: list[tuple[str, str, int]] = field(default_factory=list)  # key, value, line
    rows: list[tuple[str, int]] = field(default_factory=list)  # [Rules]


_HEADER = re.compile(r"^\[\s*([A-Za-z]+)\s*(\d*)\s*\]$")
_ENTRY = re.compile(r"^([A-Za-z]+\d*)\s*=\s*(.*)$")
_MF = re.compile(r"""^(['"])(.*?)\1\s*:\s*(['"])(.*?)\3\s*,\s*\[(.*)\]$""")
_RULE = re.compile(r"^([^,]*),([^(]*)\(([^)]*)\)\s*:\s*(\S+)$")


def read_fis(path: str | os.PathLike[str]) -> Fis:
    """Parse the .fis file at `path` (FisError: file, line, section)."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > MAX_FILE_BYTES:
            raise FisError(f"{p}: {size} bytes is larger than any FIS file pamd reads "
                           f"({MAX_FILE_BYTES} at most)")
        raw = p.read_bytes()
    except OSError as exc:
        raise FisError(f"{p}: cannot read it ({exc})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")  # MATLAB on Windows writes the local code page
    return parse_fis(text, str(p))


def parse_fis(text: str, source: str = "<fis>") -> Fis:
    """Parse .fis text; `source` names it in errors."""
    sections = _sections(text, source)
    system = next((s for s in sections if s.name == "System"), None)
    if system is None:
        raise FisError(f"{source}:1: no [System] section: not a MATLAB FIS file")
    values = {k: (_unquote(v), n) for k, v, n in system.entries}
    inputs = tuple(_variable(s, source) for s in sections if s.name.startswith("Input"))
    outputs = tuple(_variable(s, source) for s in sections if s.name.startswith("Output"))
    rules_section = next((s for s in sections if s.name == "Rules"), None)
    rules = tuple(_rule(row, n, source) for row, n in rules_section.rows) if rules_section \
        else ()
    fis = Fis(source, values, system.line, inputs, outputs, rules,
              rules_section.line if rules_section else system.line)
    _check_counts(fis, sections)
    return fis


def _sections(text: str, source: str) -> list[_Section]:
    out: list[_Section] = []
    for n, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line[0] in "%#":
            continue
        head = _HEADER.match(line)
        if head:
            out.append(_Section(head.group(1) + head.group(2), n))
            continue
        if not out:
            raise FisError(f"{source}:{n}: text before the first section ([System])")
        sec = out[-1]
        if sec.name == "Rules":
            sec.rows.append((line, n))
            continue
        entry = _ENTRY.match(line)
        if not entry:
            raise FisError(f"{source}:{n}: [{sec.name}] expected KEY=VALUE, found {line!r}")
        sec.entries.append((entry.group(1), entry.group(2).strip(), n))
    return out


def _unquote(value: str) -> str:
    if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"":
        return value[1:-1]
    return value


def _numbers(text: str, where: str, source: str, line: int) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in re.split(r"[\s,]+", text.strip()) if v)
    except ValueError:
        raise FisError(f"{source}:{line}: [{where}] expected numbers, found "
                       f"[{text}]") from None
    if not all(math.isfinite(v) for v in vals):
        raise FisError(f"{source}:{line}: [{where}] a number that is not finite: [{text}]")
    return vals


def _variable(sec: _Section, source: str) -> FisVar:
    keys = {k: (v, n) for k, v, n in sec.entries}
    for key in ("Name", "Range", "NumMFs"):
        if key not in keys:
            raise FisError(f"{source}:{sec.line}: [{sec.name}] no {key}= line")
    name, name_line = _unquote(keys["Name"][0]), keys["Name"][1]
    rtext, rline = keys["Range"]
    rng = _numbers(rtext.strip().lstrip("[").rstrip("]"), sec.name, source, rline)
    if len(rng) != 2 or not rng[0] <= rng[1]:
        raise FisError(f"{source}:{rline}: [{sec.name}] Range={rtext}: expected [low high]")
    mfs = []
    for key, value, n in sec.entries:
        if not re.fullmatch(r"MF\d+", key):
            continue
        m = _MF.match(value)
        if not m:
            raise FisError(f"{source}:{n}: [{sec.name}] expected {key}='name':'type',[params],"
                           f" found {value!r}")
        mfs.append(FisMf(int(key[2:]), m.group(2), m.group(4),
                         _numbers(m.group(5), sec.name, source, n), n))
    count_text, count_line = keys["NumMFs"]
    if not count_text.isdigit() or int(count_text) != len(mfs):
        raise FisError(f"{source}:{count_line}: [{sec.name}] NumMFs={count_text} but "
                       f"{len(mfs)} MF lines follow")
    for k, mf in enumerate(mfs, start=1):
        if mf.index != k:
            raise FisError(f"{source}:{mf.line}: [{sec.name}] MF{mf.index} where MF{k} is "
                           "expected (MF1, MF2, ... in order)")
    return FisVar(sec.name, sec.line, name, name_line, (rng[0], rng[1]), rline, tuple(mfs))


def _rule(row: str, n: int, source: str) -> FisRule:
    m = _RULE.match(row)
    if not m:
        raise FisError(f"{source}:{n}: [Rules] expected 'i1 i2 ..., o (weight) : "
                       f"connection', found {row!r}")
    ante = _numbers(m.group(1), "Rules", source, n)
    cons = _numbers(m.group(2), "Rules", source, n)
    weight = _numbers(m.group(3), "Rules", source, n)
    if len(cons) != 1 or len(weight) != 1:
        raise FisError(f"{source}:{n}: [Rules] one output MF and one weight a rule "
                       f"(pamd's models have one output), found {row!r}")
    if not m.group(4).isdigit() or int(m.group(4)) not in (1, 2):
        raise FisError(f"{source}:{n}: [Rules] connection {m.group(4)!r}: 1 (AND) or 2 (OR)")
    return FisRule(ante, cons[0], weight[0], int(m.group(4)), n)


def _check_counts(fis: Fis, sections: list[_Section]) -> None:
    for key, found, what in (("NumInputs", len(fis.inputs), "[InputN] sections"),
                             ("NumOutputs", len(fis.outputs), "[OutputN] sections"),
                             ("NumRules", len(fis.rules), "lines in [Rules]")):
        value = fis.value(key)
        if not value.isdigit() or int(value) != found:
            raise fis.error(fis.line_of(key), "System", f"{key}={value} but the file has "
                            f"{found} {what}")
    for kind, vars_ in (("Input", fis.inputs), ("Output", fis.outputs)):
        for k, var in enumerate(vars_, start=1):
            if var.section != f"{kind}{k}":
                raise fis.error(var.line, var.section, f"where [{kind}{k}] is expected "
                                "(numbered from 1, in order)")
    known = {"System", "Rules"}
    for sec in sections:
        if sec.name not in known and not re.fullmatch(r"(Input|Output)\d+", sec.name):
            raise fis.error(sec.line, sec.name, "is not a section of a FIS file")


# -- .fis -> pamd model -------------------------------------------------------------------
@dataclass(frozen=True)
class Imported:
    """A model read from a .fis, and what the import says about it."""

    model: AnfisModel
    notes: tuple[str, ...]


def import_fis(path: str | os.PathLike[str], *, inputs: Sequence[str] | None = None,
               output: str | None = None, kind: str = "anfis",
               velocity_window_s: float | None = None) -> Imported:
    """The pamd model of the Sugeno FIS at `path` (FisError naming the line and section
    of what pamd's model cannot hold). `inputs` names the model's inputs in the file's
    order (pamd signals; default: the file's Name= fields), `output` its output."""
    fis = read_fis(path)
    data = Path(path).read_bytes()
    source: JsonObject = {
        "from": str(path), "sha256": hashlib.sha256(data).hexdigest(),
        "format": f"MATLAB FIS (Fuzzy Logic Toolbox .fis), Version={fis.value('Version')}",
        "fis_name": fis.value("Name"), "pamd_version": __version__}
    return to_model(fis, inputs=inputs, output=output, kind=kind,
                    velocity_window_s=velocity_window_s, source=source)


def to_model(fis: Fis, *, inputs: Sequence[str] | None = None, output: str | None = None,
             kind: str = "anfis", velocity_window_s: float | None = None,
             source: JsonObject | None = None) -> Imported:
    """`import_fis` on a parsed file (`source`: where it came from, for the model's
    provenance)."""
    if kind not in KINDS:
        raise FisError(f"--kind {kind}: a FIS becomes one of {', '.join(KINDS)}")
    _check_system(fis)
    names, notes = _signal_names(fis, inputs, output)
    mf_type = _mf_shape(fis)
    out_var = fis.outputs[0]
    rows = _grid_rules(fis)
    linear = _consequent_rows(fis, rows)
    lo, hi = _input_ranges(fis)
    span = hi - lo
    centres, widths, slopes = [], [], []
    for i, v in enumerate(fis.inputs):
        c, w, b = _scaled_mfs(fis, v, float(lo[i]), float(span[i]))
        centres.append(c)
        widths.append(w)
        slopes.append(b)
    consequents, consequent = _scaled_consequents(linear, lo, span)
    window = MODEL_VELOCITY_WINDOW_S if velocity_window_s is None else velocity_window_s
    if "velocity_mm_s" in names[0]:
        notes.append(f"velocity_mm_s is filtered as pamd filters it for a model: a "
                     f"first-order low-pass of the length's backward difference, window "
                     f"{window:g} s (--velocity-window-s: the one the FIS was trained with)")
    in_vars = [Variable(n, INPUT_UNITS[n], float(lo[i]), float(hi[i]))
               for i, n in enumerate(names[0])]
    out = Variable(names[1], OUTPUT_UNITS[names[1]], out_var.range[0], out_var.range[1])
    imported: JsonObject = dict(source or {})
    imported["names"] = {v.name: n for v, n in zip((*fis.inputs, out_var),
                                                    (*names[0], names[1]), strict=True)}
    imported["units"] = {v.name: v.unit for v in (*in_vars, out)}
    prov: JsonObject = {"imported": imported}
    model = AnfisModel(in_vars, out, mf_type=mf_type, scaling="minmax", scale_offset=lo,
                       scale_span=span, centres=centres, widths=widths,
                       slopes=slopes if mf_type == "bell" else None,
                       consequents=consequents,
                       derived_inputs=derived_inputs(names[0], window), provenance=prov,
                       consequent=consequent)
    model.kind = kind
    notes.insert(0, "values taken in the signals' own units: " + ", ".join(
        f"{v.name} [{v.unit or '1'}]" for v in in_vars) + f" -> {out.name} "
        f"[{out.unit or '1'}]")
    return Imported(model, tuple(notes))


def _scaled_consequents(linear: list[list[float]], lo: np.ndarray, span: np.ndarray
                        ) -> tuple[np.ndarray, str]:
    """(the rules' [p, q] on the scaled inputs, "linear" or "constant": every p 0)."""
    # f = sum p_i x_i + q with x_i = lo_i + span_i s_i: p_s = p span, q_s = q + p . lo
    raw = np.array(linear, dtype=np.float64)
    consequents = np.column_stack([raw[:, :-1] * span, raw[:, -1] + raw[:, :-1] @ lo])
    if np.any(raw[:, :-1]):
        return consequents, "linear"
    return np.column_stack([np.zeros_like(consequents[:, :-1]), consequents[:, -1]]), "constant"


def _input_ranges(fis: Fis) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of the inputs' ranges, each of some width (pamd scales an input over
    it)."""
    lo = np.array([v.range[0] for v in fis.inputs])
    hi = np.array([v.range[1] for v in fis.inputs])
    for v in fis.inputs:
        if not v.range[1] > v.range[0]:
            raise fis.error(v.range_line, v.section, f"Range=[{v.range[0]:g} "
                            f"{v.range[1]:g}] has no width: pamd scales an input over it")
    return lo, hi


def _check_system(fis: Fis) -> None:
    typ = fis.value("Type")
    if typ.lower() != "sugeno":
        raise fis.error(fis.line_of("Type"), "System", f"Type='{typ}': pamd imports Sugeno "
                        "systems (linear or constant outputs, as ANFIS trains them); a "
                        f"{typ} system has no such form")
    try:
        version = float(fis.value("Version"))
    except ValueError:
        raise fis.error(fis.line_of("Version"), "System",
                        f"Version={fis.value('Version')}: not a number") from None
    if not 1.0 <= version < 4.0:
        raise fis.error(fis.line_of("Version"), "System", f"Version={version:g}: pamd reads "
                        "FIS files of versions 1.0 to 3.0")
    if len(fis.outputs) != 1:
        raise fis.error(fis.line_of("NumOutputs"), "System", f"NumOutputs={len(fis.outputs)}:"
                        " a pamd model has one output")
    if not fis.inputs:
        raise fis.error(fis.line_of("NumInputs"), "System", "NumInputs=0: no inputs")
    if len(fis.inputs) > 1 and fis.value("AndMethod") != "prod":
        raise fis.error(fis.line_of("AndMethod"), "System",
                        f"AndMethod='{fis.value('AndMethod')}': pamd's rules fire with the "
                        "product of their memberships (AndMethod='prod', as ANFIS)")
    if fis.value("DefuzzMethod") != "wtaver":
        raise fis.error(fis.line_of("DefuzzMethod"), "System",
                        f"DefuzzMethod='{fis.value('DefuzzMethod')}': pamd's output is the "
                        "weighted average of the rules' outputs (DefuzzMethod='wtaver')")


def _signal_names(fis: Fis, inputs: Sequence[str] | None, output: str | None
                  ) -> tuple[tuple[list[str], str], list[str]]:
    """The pamd signal of each input and of the output: --inputs/--output, else the
    file's Name= fields."""
    notes: list[str] = []
    if inputs is not None and len(inputs) != len(fis.inputs):
        raise fis.error(fis.line_of("NumInputs"), "System",
                        f"NumInputs={len(fis.inputs)} but --inputs names {len(inputs)}: one "
                        "pamd signal per input, in the file's order")
    names = []
    for k, var in enumerate(fis.inputs):
        name = inputs[k] if inputs is not None else var.name
        if name not in INPUT_UNITS:
            given = "--inputs gives" if inputs is not None else f"Name='{var.name}' is"
            raise fis.error(var.name_line, var.section, f"{given} {name!r}, not a pamd "
                            f"signal ({', '.join(INPUT_UNITS)}): name the inputs with "
                            "--inputs, one per input in the file's order")
        if name != var.name:
            notes.append(f"[{var.section}] Name='{var.name}' is {name}")
        names.append(name)
    if len(set(names)) != len(names):
        raise fis.error(fis.inputs[0].line, "Input1", f"inputs {names}: a signal twice")
    out_var = fis.outputs[0]
    out = output if output is not None else out_var.name
    if out not in OUTPUT_UNITS:
        given = "--output gives" if output is not None else f"Name='{out_var.name}' is"
        raise fis.error(out_var.name_line, out_var.section, f"{given} {out!r}, not a signal "
                        f"a pamd model predicts ({', '.join(OUTPUT_UNITS)}): name it with "
                        "--output")
    if out != out_var.name:
        notes.append(f"[{out_var.section}] Name='{out_var.name}' is {out}")
    return (names, out), notes


def _mf_shape(fis: Fis) -> str:
    """pamd's one MF shape for every input (the types the file's input MFs have)."""
    first: FisMf | None = None
    for var in fis.inputs:
        if not var.mfs:
            raise fis.error(var.line, var.section, "NumMFs=0: an input without MFs")
        for mf in var.mfs:
            if mf.type not in INPUT_MFS:
                raise fis.error(mf.line, var.section, f"MF{mf.index} type '{mf.type}' is not"
                                f" one pamd implements ({', '.join(INPUT_MFS)})")
            need = len(INPUT_MFS[mf.type][1])
            if len(mf.params) != need:
                raise fis.error(mf.line, var.section, f"MF{mf.index} '{mf.type}' takes "
                                f"{need} parameters [{' '.join(INPUT_MFS[mf.type][1])}], "
                                f"found {len(mf.params)}")
            if first is None:
                first = mf
            elif mf.type != first.type:
                raise fis.error(mf.line, var.section, f"MF{mf.index} is '{mf.type}' but line "
                                f"{first.line} is '{first.type}': pamd's model has one MF "
                                "shape for every input")
    assert first is not None
    return INPUT_MFS[first.type][0]


def _scaled_mfs(fis: Fis, var: FisVar, lo: float, span: float
                ) -> tuple[list[float], list[float], list[float]]:
    """The input's MFs on s = (x - lo) / span: centre (c - lo) / span, width / span."""
    centres, widths, slopes = [], [], []
    for mf in var.mfs:
        if mf.type == "gaussmf":
            sigma, c = mf.params
            b = 0.0
        else:
            sigma, b, c = mf.params
        if sigma == 0.0:
            raise fis.error(mf.line, var.section, f"MF{mf.index} has width 0")
        centres.append((c - lo) / span)
        widths.append(abs(sigma) / span)  # the sign of a width is immaterial in both
        slopes.append(b)
    return centres, widths, slopes


def _grid_rules(fis: Fis) -> list[FisRule]:
    """The rules in pamd's grid order (every combination of the inputs' MFs once, last
    input fastest), each checked against the MFs it names."""
    n_mfs = [len(v.mfs) for v in fis.inputs]
    n_out = len(fis.outputs[0].mfs)
    first = fis.rules[0] if fis.rules else None
    by_mfs: dict[tuple[int, ...], FisRule] = {}
    for k, rule in enumerate(fis.rules, start=1):
        where = f"rule {k}"
        key = _rule_mfs(fis, rule, where, n_mfs)
        _check_rule_form(fis, rule, where, n_out, len(n_mfs), first)
        if key in by_mfs:
            raise fis.error(rule.line, "Rules", f"{where} repeats the MFs of line "
                            f"{by_mfs[key].line}")
        by_mfs[key] = rule
    grid = list(itertools.product(*(range(m) for m in n_mfs)))
    missing = [g for g in grid if g not in by_mfs]
    if missing:
        raise fis.error(fis.rules_line, "Rules", f"{len(fis.rules)} rules for a grid of "
                        f"{len(grid)} ({' x '.join(map(str, n_mfs))} MFs): no rule for MFs "
                        f"{' '.join(str(m + 1) for m in missing[0])}; pamd's model has one "
                        "rule for every combination of the inputs' MFs (a grid partition)")
    return [by_mfs[g] for g in grid]


def _rule_mfs(fis: Fis, rule: FisRule, where: str, n_mfs: list[int]) -> tuple[int, ...]:
    """The MF (0-based) the rule names of each input: one of every input, each one the
    input has."""
    if len(rule.antecedent) != len(n_mfs):
        raise fis.error(rule.line, "Rules", f"{where} names {len(rule.antecedent)} input "
                        f"MFs for {len(n_mfs)} inputs")
    mfs = []
    for i, (a, m) in enumerate(zip(rule.antecedent, n_mfs, strict=True)):
        if a != int(a) or a <= 0:
            raise fis.error(rule.line, "Rules", f"{where}: input {i + 1} MF {a:g}: pamd's "
                            "rules name one MF of every input (no 0 for 'any', no "
                            "negative 'not', no hedges)")
        if a > m:
            raise fis.error(rule.line, "Rules", f"{where} names MF {int(a)} of input "
                            f"{i + 1}, which has {m} ([{fis.inputs[i].section}] NumMFs "
                            f"at line {fis.inputs[i].line})")
        mfs.append(int(a) - 1)
    return tuple(mfs)


def _check_rule_form(fis: Fis, rule: FisRule, where: str, n_out: int, n_inputs: int,
                     first: FisRule | None) -> None:
    """The rule names an output MF there is, is an AND rule (with more than one input)
    and weighs as rule 1 does (above 0)."""
    if rule.consequent != int(rule.consequent) or not 1 <= rule.consequent <= n_out:
        raise fis.error(rule.line, "Rules", f"{where} names output MF "
                        f"{rule.consequent:g}; [Output1] has {n_out}")
    if rule.connection == 2 and n_inputs > 1:
        raise fis.error(rule.line, "Rules", f"{where} is an OR rule (connection 2): "
                        "pamd's rules are AND (the product of their MFs)")
    if rule.weight <= 0 or (first is not None and rule.weight != first.weight):
        raise fis.error(rule.line, "Rules", f"{where} has weight {rule.weight:g} where "
                        f"rule 1 has {first.weight if first else 0:g}: pamd's rules "
                        "weigh alike (one weight > 0 for every rule)")


def _consequent_rows(fis: Fis, rules: list[FisRule]) -> list[list[float]]:
    """Each rule's output [p_1 .. p_d, q] in raw units (constant: p = 0)."""
    out_var = fis.outputs[0]
    d = len(fis.inputs)
    rows = []
    for rule in rules:
        mf = out_var.mfs[int(rule.consequent) - 1]
        if mf.type not in OUTPUT_MFS:
            raise fis.error(mf.line, out_var.section, f"MF{mf.index} type '{mf.type}': a "
                            "Sugeno output is 'linear' or 'constant'")
        need = d + 1 if mf.type == "linear" else 1
        if len(mf.params) != need:
            raise fis.error(mf.line, out_var.section, f"MF{mf.index} '{mf.type}' takes "
                            f"{need} parameters, found {len(mf.params)}")
        rows.append(list(mf.params) if mf.type == "linear" else [0.0] * d + [mf.params[0]])
    return rows


# -- pamd model -> .fis ---------------------------------------------------------------------
def fis_text(model: InverseModel, name: str) -> str:
    """The .fis text of a pamd Sugeno model (kind anfis or ts-fuzzy), in raw units."""
    if not isinstance(model, AnfisModel):
        raise ModelError(f"a {model.kind} model has no FIS form: only the Sugeno fuzzy kinds "
                         f"({', '.join(KINDS)}) are MATLAB FIS systems")
    o, sp = model.scale_offset, model.scale_span
    d = model.n_inputs
    lines = ["[System]", f"Name={_quote(name)}", "Type='sugeno'", f"Version={VERSION}",
             f"NumInputs={d}", "NumOutputs=1", f"NumRules={model.n_rules}",
             "AndMethod='prod'", "OrMethod='probor'", "ImpMethod='prod'", "AggMethod='sum'",
             "DefuzzMethod='wtaver'"]
    mf = MATLAB_MF[model.mf_type]
    for i, v in enumerate(model.inputs):
        lines += ["", f"[Input{i + 1}]", f"Name={_quote(v.name)}",
                  f"Range=[{_num(v.min)} {_num(v.max)}]", f"NumMFs={model.n_mfs[i]}"]
        for k in range(model.n_mfs[i]):
            c = o[i] + sp[i] * model.centres[i][k]
            w = sp[i] * model.widths[i][k]
            if model.slopes is None:
                params = [w, c]
            else:
                params = [w, model.slopes[i][k], c]
            lines.append(f"MF{k + 1}='in{i + 1}mf{k + 1}':'{mf}',{_vector(params)}")
    # f = sum p_i (x_i - o_i) / sp_i + q: p_i / sp_i on x_i, q - sum p_i o_i / sp_i
    p = model.consequents[:, :-1] / sp
    q = model.consequents[:, -1] - p @ o
    linear = model.consequent == "linear"
    out = model.output
    lines += ["", "[Output1]", f"Name={_quote(out.name)}",
              f"Range=[{_num(out.min)} {_num(out.max)}]", f"NumMFs={model.n_rules}"]
    for r in range(model.n_rules):
        params = [*p[r], q[r]] if linear else [model.consequents[r, -1]]
        lines.append(f"MF{r + 1}='out1mf{r + 1}':'{'linear' if linear else 'constant'}',"
                     f"{_vector(params)}")
    lines += ["", "[Rules]"]
    for r, mfs in enumerate(model.rule_mfs):
        lines.append(" ".join(str(m + 1) for m in mfs) + f", {r + 1} (1) : 1")
    return "\n".join(lines) + "\n"


def export_fis(model: InverseModel, path: str | os.PathLike[str],
               name: str | None = None) -> tuple[Path, list[str]]:
    """Write `model` as a .fis file (atomically: a temporary file renamed); returns the
    path and what the file cannot carry (said to the user)."""
    target = Path(path)
    text = fis_text(model, name or target.stem)
    notes = []
    window = (model.derived_inputs.get("velocity_mm_s") or {}).get("window_s")
    if window is not None:
        notes.append(f"velocity_mm_s is pamd's filtered length rate (window {window:g} s), "
                     f"which a .fis cannot state: `pamd model import {target.name} "
                     f"--velocity-window-s {window:g}` restores it")
    notes.append("pamd holds inputs outside a model's ranges to them; MATLAB's evalfis "
                 "evaluates them (with a warning)")
    write_atomic(target, text)  # whole or not at all: FileWriteError names it
    return target, notes


def _num(v: float) -> str:
    """A float as MATLAB's str2num reads it back exactly (the shortest repr)."""
    x = float(v)
    return "0" if x == 0.0 else repr(x)


def _vector(values: Sequence[float] | np.ndarray) -> str:
    return "[" + " ".join(_num(float(v)) for v in values) + "]"


def _quote(text: str) -> str:
    if "'" in text or "\n" in text:
        raise ModelError(f"name {text!r}: a FIS name cannot hold a quote or a line break")
    return f"'{text}'"


def names_given(text: str | None) -> list[str] | None:
    """`--inputs a,b,c`: the names, or None."""
    if text is None:
        return None
    return [s.strip() for s in text.split(",") if s.strip()]


