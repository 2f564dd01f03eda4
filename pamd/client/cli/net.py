"""`pamd status`, `pamd cmd`, `pamd watch`: clients of a running daemon over Zenoh (or,
on the rig PC, its local channel: `pamd.wire.local_channel`); `pamd token`: the command
credential's file, rotated on demand.

`pamd status` and `pamd cmd` use the daemon's local channel when it is on this machine
(no `--zenoh-config`, and `--connect`, if given, a loopback endpoint it listens on), so
no number of Zenoh sessions can keep them out. Otherwise each opens its own Zenoh
session in client mode: to `tcp/127.0.0.1:7447` by default, to `--connect ENDPOINT`,
or as `--zenoh-config FILE` says (a client config such as config/zenoh/lab-client.json5;
given a daemon's config, it connects where that daemon listens). With no `--rig`, the
one rig alive is used (several: refused, listing them); a rig id is a name, never a
pattern. Commands are signed with the daemon's token (`pamd.wire.credential`;
`--token-file`). Exit codes: 0 ok, 4 command refused, 7 no
daemon answers (or not allowed), 2 bad arguments, config or rig name.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys
import textwrap
import time
import typing
from collections.abc import Callable
from enum import IntEnum

from pamd.client.cli.numbers import number
from pamd.client.remote import Client, LocalRig, local_rig, rig_name
from pamd.wire.credential import CredentialError, find_token, rotate_token
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import CommandRefused
from pamd.wire.keys import Keys
from pamd.wire.telemetry import decode
from pamd.wire.tick import Mode, State
from pamd.wire.verbs.table import VERBS, parse_command
from pamd.wire.zconf import NoDaemon

CMD_EPILOG = """examples:
  pamd cmd setpoint --muscle m1 --bar 3.0
  pamd cmd setpoint --muscle m1 --bar 3.0 --deadman-s 0.5     # streamed: refresh it
  pamd cmd profile --shape sine --min-bar 0 --max-bar 6 --freq-hz 0.05 --cycles 2
  pamd cmd hold ; pamd cmd stop ; pamd cmd estop --reason "hand in the rig"
  pamd cmd collect --plan-file sweep.yaml     # by name, from the daemon's telemetry.plans_dir
  pamd cmd model --muscle m1 --file m1.json   # by name, from its telemetry.models_dir
  pamd cmd load --arg muscle=m1 --arg load_kg=40
  pamd cmd setpoint --json '{"muscle": "m1", "bar": 2.5}'
"""


HELP_WIDTH = 88  # `pamd cmd --help`'s own paragraphs


def add_client_args(p: argparse.ArgumentParser, suppress: bool = False) -> None:
    """The options of every command that talks to a running daemon over Zenoh."""
    d: str | None = argparse.SUPPRESS if suppress else None
    p.add_argument("--rig", default=d, help="rig id (default: the one rig alive)")
    p.add_argument("--zenoh-config", metavar="FILE", default=d,
                   help="Zenoh client config (JSON5), e.g. config/zenoh/lab-client.json5")
    p.add_argument("--connect", metavar="ENDPOINT", default=d,
                   help="connect here (default: tcp/127.0.0.1:7447); a loopback endpoint of "
                   "a daemon on this machine: status and cmd use its local channel")
    p.add_argument("--timeout", type=number("s", gt=0.0), metavar="S", default=d,
                   help="how long to wait for an answer (status 3 s; cmd, model save 10 s)")
    p.add_argument("--no-local", action="store_true", default=d,
                   help="over Zenoh even on the rig PC (by default status and cmd use the "
                   "daemon's local channel there, which no number of Zenoh sessions can "
                   "block: see --connect)")
    p.add_argument("--token-file", metavar="FILE", default=d,
                   help="the daemon's command credential (default: $PAMD_TOKEN_FILE, "
                   "$PAMD_TOKEN, else pamd-<rig>.token where the daemon writes it: "
                   "$PAMD_TOKEN_DIR, $XDG_RUNTIME_DIR/pamd, /tmp/pamd-<uid>, /run/pamd)")


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    s = sub.add_parser("status", help="ask a running daemon how it is (over Zenoh)",
                       description="The daemon's status: state, faults, limits, datums, "
                       "timing, profile and model, config hash.")
    add_client_args(s)
    s.add_argument("--json", action="store_true", help="print the status as JSON")
    s.set_defaults(func=status)

    c = sub.add_parser("cmd", help="command a running daemon (over Zenoh)",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description=textwrap.fill(
                           "Send one command; the reply is the loop's verdict. Options after "
                           "VERB are the verb's fields (--muscle, --bar, ...; `pamd cmd VERB "
                           "--help` lists them), --arg KEY=VALUE (JSON value) or --json "
                           "PAYLOAD.", HELP_WIDTH) + "\n\nverbs:\n" + verb_list(),
                       epilog=CMD_EPILOG)
    add_client_args(c)
    c.add_argument("--user", help="the user the command declares (default: your login; "
                   "recorded, not authenticated)")
    c.add_argument("verb", help=", ".join(VERBS.names))
    c.add_argument("rest", nargs=argparse.REMAINDER, help="the verb's options")
    c.set_defaults(func=cmd)

    k = sub.add_parser("token", help="where a rig's command credential is; a new one "
                       "with --rotate", description="The command credential (pamd.wire."
                       "credential): the token file a daemon keeps for its rig, with which "
                       "pamd cmd and pamd.connect sign each command (the token itself never "
                       "travels). --rotate writes a new token over the old one atomically: "
                       "a running daemon takes it within a second, and commands signed "
                       "with the old one are refused from then on (nothing to delete, no "
                       "restart).", epilog="example: pamd token --rig sim --rotate")
    k.add_argument("--rig", required=True, help="the rig id")
    k.add_argument("--token-file", metavar="FILE", help="the token file (default: where "
                   "the daemon writes it, as pamd cmd finds it)")
    k.add_argument("--rotate", action="store_true", help="replace the token with a new one")
    k.set_defaults(func=token)

    w = sub.add_parser("watch", help="live table of a running daemon's muscles (over Zenoh)",
                       description="Each muscle's latest state and the message rate, "
                       "refreshed twice a second, plus the latest events.")
    add_client_args(w)
    w.add_argument("--duration", type=number("s", gt=0.0), metavar="S",
                   help="stop after S seconds")
    w.add_argument("--plain", action="store_true", help="append tables instead of redrawing")
    w.set_defaults(func=watch)


def _client(args: argparse.Namespace) -> Client:

    return Client(args.zenoh_config, args.connect, getattr(args, "token_file", None))


def _channel(args: argparse.Namespace) -> Client | LocalRig:
    """On the rig PC, the daemon's local channel (pamd.wire.local_channel: no Zenoh session, so
    no number of them keeps a status or an estop out): when no Zenoh config is named
    and --connect, if given, is a loopback endpoint the daemon listens on. Else (or
    with no local channel found) a Zenoh session."""
    if not args.zenoh_config and not getattr(args, "no_local", False):
        local = local_rig(args.rig, args.connect)
        if local is not None:
            return local
    return _client(args)


# -- status ------------------------------------------------------------------------------
def status(args: argparse.Namespace) -> int:
    with _channel(args) as cl:
        rig = cl.rig(args.rig)
        st = cl.status(rig, args.timeout or 3.0)
        via = cl.where
    if args.json:
        print(json.dumps(st, indent=2))
    else:
        print_status(st, via)
    return 0 if st.get("ok", True) else 1


def _f(v: JsonValue, fmt: str = ".3f") -> str:
    return "-" if v is None else format(v, fmt) if isinstance(v, (int, float)) else str(v)


def print_status(st: JsonObject, via: str = "") -> None:
    if not st.get("ok", True):
        print(f"status: {st.get('error')}")
        return
    print(f"rig {st.get('rig_id')} (daemon of {st.get('user') or '?'}, pid "
          f"{st.get('pid') or '?'}): {st.get('state')} ({st.get('reason')})"
          + (f" [via {via}]" if via else ""))
    _print_warnings(st)
    _print_latched(st)
    for name, m in (st.get("muscles") or {}).items():
        _print_muscle(name, m)
    _print_timing(st)
    _print_run(st)


def _print_warnings(st: JsonObject) -> None:
    """What the daemon warns of: its warnings, stale values, lost records, live lag."""
    for warning in st.get("warnings") or []:
        print(f"  WARNING: {warning}")
    for why in st.get("stale_reasons") or []:
        print(f"  STALE: {why}")
    lost = st.get("lost_records")
    if isinstance(lost, int) and lost > 0:
        print(f"  LOST TICK RECORDS: {lost} so far (the io process fell behind and its ring "
              "was full: recording and telemetry miss them; see the lost_records events)")
    lag = st.get("live_lag_s")
    if isinstance(lag, (int, float)) and lag >= 1.0:
        print(f"  live values {lag:.1f} s behind the loop (the io process is busy)")


def _print_latched(st: JsonObject) -> None:
    """What holds: a latched fault, a stopped recording, a stop under way."""
    if st.get("fault"):
        print(f"  latched fault: {st['fault']}")
    failure = (st.get("recording") or {}).get("failure")
    if failure:
        print(f"  RECORDING STOPPED: {failure.get('reason')} (recording.on_"
              f"{'io_death' if failure.get('what') == 'death' else 'failure'}: "
              f"{failure.get('policy')})")
    if st.get("stopping"):
        print(f"  stopping: {st['stopping']}")


def _print_muscle(name: str, m: JsonObject) -> None:
    """One muscle: its values, limits and datums, and its model (an older daemon says
    its datums under their old names only: `pamd.wire.declare.deprecated`)."""
    lim, datums = m.get("limits") or {}, m.get("datums") or m.get("references") or {}
    has_datum = m.get("has_length_datum", m.get("referenced"))
    print(f"  {name}: {_f(m.get('pressure_bar'))} bar (setpoint "
          f"{_f(m.get('setpoint_bar'))}, valve {_f(m.get('valve_cmd_bar'))}), force "
          f"{_f(m.get('force_n'), '.1f')} N, length {_f(m.get('length_mm'), '.2f')} mm, "
          f"mode {m.get('mode')}, profile {m.get('profile') or '-'}")
    print(f"      limits {_f(lim.get('max_pressure_bar'), 'g')} bar, contraction "
          f"{_f(lim.get('max_contraction'), 'g')}, pretension "
          f"{_f(lim.get('max_pretension'), 'g')}; safe pressure "
          f"{_f(m.get('safe_pressure_bar'), '.2f')} bar at {_f(m.get('load_kg'), 'g')} "
          f"kg; length datum {'yes' if has_datum else 'no'} (homed "
          f"{datums.get('homed_at') or '-'}, tared {datums.get('tared_at') or '-'})")
    model = m.get("model")
    if model:
        print(f"      model {model.get('file')} ({model.get('rules')} rules)")


def _print_timing(st: JsonObject) -> None:
    """The loop's rate, clock, ticks, overruns, wake-up lateness and compute time."""
    t = st.get("timing") or {}
    if t:
        w, c = t.get("wake_latency_us", {}), t.get("compute_us", {})
        print(f"  loop: {st.get('rate_hz')} Hz {st.get('clock')} clock, {t.get('ticks')} ticks,"
              f" {t.get('overruns')} overruns; wake-up p50/p99/max {_f(w.get('p50'), '.0f')}/"
              f"{_f(w.get('p99'), '.0f')}/{_f(w.get('max'), '.0f')} us; compute p99 "
              f"{_f(c.get('p99'), '.0f')} us")


def _print_run(st: JsonObject) -> None:
    """The experiment under way, this run's faults, the config and the snapshot's age."""
    if st.get("experiment"):
        e = st["experiment"]
        print(f"  experiment {e.get('plan')}: step {e.get('step')} {e.get('phase')}"
              + (f" - {e['awaiting_operator']}" if e.get("awaiting_operator") else ""))
    if st.get("faults"):
        print(f"  faults this run: {'; '.join(st['faults'])}")
    print(f"  config {st.get('config_path')} sha256 {str(st.get('config_sha256'))[:16]}..., "
          f"snapshot {_f(st.get('snapshot_age_s'), '.2f')} s old")


# -- cmd ---------------------------------------------------------------------------------
def _parse_bool(text: str) -> bool:
    t = text.strip().lower()
    if t in ("true", "1", "yes", "on"):
        return True
    if t in ("false", "0", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected true or false, found {text!r}")


def _json_value(text: str) -> JsonValue:
    try:
        return json.loads(text)
    except ValueError:
        return text


def _field_type(tp: object) -> Callable[[str], object]:
    args = [a for a in typing.get_args(tp) if a is not type(None)] or [tp]
    base = args[0]
    parsers: dict[object, Callable[[str], object]] = {bool: _parse_bool, int: int, float: float}
    return parsers.get(base, str)


def verb_list() -> str:
    """One line per verb a client may send, from its declaration."""
    width = max(len(v.name) for v in VERBS)
    return "\n".join(textwrap.fill(v.help, HELP_WIDTH,
                                   initial_indent=f"  {v.name.ljust(width)}  ",
                                   subsequent_indent=" " * (width + 4)) for v in VERBS)


def verb_parser(verb: str) -> argparse.ArgumentParser:
    """The options of one verb, from its argument dataclass."""
    declared = VERBS.public(verb)
    p = argparse.ArgumentParser(prog=f"pamd cmd {verb}", add_help=True,
                                description=declared.help if declared else None)
    add_client_args(p, suppress=True)
    p.add_argument("--user", default=argparse.SUPPRESS)
    p.add_argument("--arg", action="append", default=[], metavar="KEY=VALUE",
                   help="a field, VALUE parsed as JSON when it can be")
    p.add_argument("--json", metavar="PAYLOAD", help="the whole payload, sent as given")
    if declared is not None:
        hints = typing.get_type_hints(declared.args)
        for f in dataclasses.fields(declared.args):
            doc = f.metadata.get("doc", "")
            unit = f.metadata.get("unit")
            flags = ["--" + f.name.replace("_", "-")]
            if "old" in f.metadata:  # the field's old name still works (`--kind`)
                flags.append("--" + f.metadata["old"].replace("_", "-"))
                doc += f" (old name: {flags[1]})"
            p.add_argument(*flags, dest=f"field_{f.name}",
                           type=_field_type(hints[f.name]), metavar=unit or "VALUE",
                           help=doc)
    return p


def build_payload(verb: str, rest: list[str], args: argparse.Namespace) -> str | JsonObject:
    ns = verb_parser(verb).parse_args(rest, namespace=args)
    if ns.json is not None:
        if ns.arg or any(k.startswith("field_") and v is not None for k, v in vars(ns).items()):
            raise SystemExit("pamd cmd: --json is the whole payload; give no other fields")
        text: str = ns.json  # --json PAYLOAD
        return text
    payload: JsonObject = {k[len("field_"):]: v for k, v in vars(ns).items()
                               if k.startswith("field_") and v is not None}
    for item in ns.arg:
        key, eq, value = item.partition("=")
        if not eq or not key:
            raise SystemExit(f"pamd cmd: --arg takes KEY=VALUE, found {item!r}")
        payload[key] = _json_value(value)
    return payload


def cmd(args: argparse.Namespace) -> int:
    payload = build_payload(args.verb, list(args.rest), args)
    if isinstance(payload, dict):  # refused here as the daemon would, before any session
        parse_command(args.verb, payload, label=lambda field: f"--{field.replace('_', '-')}")
    with _channel(args) as cl:
        rig = cl.rig(args.rig)
        verdict = cl.command(rig, args.verb, payload, user=args.user,
                             timeout_s=args.timeout or 10.0)
    print(json.dumps(verdict))
    if not verdict.get("ok"):
        raise CommandRefused(refusal(args.verb, str(verdict.get("error"))))
    return 0


def refusal(verb: str, error: str) -> str:
    """A refused command's reason, said once: the daemon's own words when they name the
    verb already ("model refused: ..."), else "VERB refused: REASON"."""
    if error.startswith((f"{verb} ", f"{verb}:")):
        return error
    return f"{verb} refused: {error}"


# -- token -------------------------------------------------------------------------------
def token(args: argparse.Namespace) -> int:
    rig = rig_name(args.rig)
    if args.rotate:
        path = rotate_token(rig, args.token_file)
        print(f"{path}: a new token (a running daemon takes it within a second)")
        return 0
    tok, where = find_token(rig, args.token_file)
    if tok is None:
        raise CredentialError(f"no command token of rig {rig!r} found (looked in {where}); "
                              "a daemon makes one as it starts")
    print(where)
    return 0


# -- watch -------------------------------------------------------------------------------
COLUMNS = ("muscle", "state", "p bar", "sp bar", "valve", "force N", "len mm", "contr %",
           "mode", "flags", "puts/s", "samples/s", "dropped")


def _name(enum: type[IntEnum], v: JsonValue) -> str:
    try:
        return enum(int(v)).name
    except (TypeError, ValueError):
        return "-"


@dataclasses.dataclass
class _Tally:
    """What `pamd watch` has received, by muscle: the latest values, the messages
    (puts) and samples counted, and the messages missed (gaps in their sequence)."""

    latest: dict[str, JsonObject] = dataclasses.field(default_factory=dict)
    puts: dict[str, int] = dataclasses.field(default_factory=dict)
    samples: dict[str, int] = dataclasses.field(default_factory=dict)
    gaps: dict[str, int] = dataclasses.field(default_factory=dict)
    last_seq: dict[str, int] = dataclasses.field(default_factory=dict)
    total: int = 0  # messages received in all

    def take(self, msg: JsonObject) -> None:
        """Count one state message and keep its last sample."""
        m = msg.get("muscle", "?")
        self.total += 1
        self.puts[m] = self.puts.get(m, 0) + 1
        self.samples[m] = self.samples.get(m, 0) + len(msg.get("tick", []))
        seq = msg.get("seq", 0)
        if m in self.last_seq and seq > self.last_seq[m] + 1:
            self.gaps[m] = self.gaps.get(m, 0) + seq - self.last_seq[m] - 1
        self.last_seq[m] = seq
        if msg.get("tick"):
            self.latest[m] = {k: v[-1] for k, v in msg.items() if isinstance(v, list)}

    def counts(self) -> dict[str, dict[str, int]]:
        """The counts so far, from which the next table's rates are measured."""
        return {"puts": dict(self.puts), "samples": dict(self.samples)}

    def rows(self, since: dict[str, dict[str, int]], dt: float) -> list[tuple[str, ...]]:
        """The table's rows (as COLUMNS), the rates over the `dt` s since `since`."""
        rows: list[tuple[str, ...]] = []
        for m, v in sorted(self.latest.items()):
            rows.append((m, _name(State, v.get("state")), _f(v.get("pressure_bar")),
                         _f(v.get("setpoint_bar")), _f(v.get("valve_cmd_bar")),
                         _f(v.get("force_n"), ".1f"), _f(v.get("length_mm"), ".2f"),
                         _f(None if v.get("contraction") is None
                            else 100 * v["contraction"], ".2f"),
                         _name(Mode, v.get("mode")), f"{int(v.get('flags') or 0):#x}",
                         f"{(self.puts[m] - since['puts'].get(m, 0)) / dt:.0f}",
                         f"{(self.samples[m] - since['samples'].get(m, 0)) / dt:.0f}",
                         str(self.gaps.get(m, 0))))
        return rows


def _latest_events(events: list[str], line: str) -> list[str]:
    """The last five event lines with `line` added."""
    return (events + [line])[-5:]


def _event_line(ev: JsonObject) -> str:
    return f"{_f(ev.get('t_s'), '.2f')} s {ev.get('kind')}: {json.dumps(ev.get('data'))[:100]}"


def watch(args: argparse.Namespace) -> int:

    with _client(args) as cl:
        rig = cl.rig(args.rig)
        keys = Keys(rig)
        sub = cl.subscribe(keys.state_all)
        evs = cl.subscribe(keys.events, 256)
        tally = _Tally()
        events: list[str] = []
        t0 = t_draw = time.monotonic()
        n_draw = tally.counts()
        redraw = sys.stdout.isatty() and not args.plain
        retry_t = 0.0
        try:
            while True:
                now = time.monotonic()
                if cl.lost and now >= retry_t:  # the daemon went: its next one, when up
                    retry_t = now + 2.0
                    gone = "(the daemon went away: waiting for it)"
                    events = events if events[-1:] == [gone] else _latest_events(events, gone)
                    with contextlib.suppress(NoDaemon):
                        sub, evs = cl.subscribe(keys.state_all), cl.subscribe(keys.events, 256)
                while (s := sub.try_recv()) is not None:
                    tally.take(decode(s.payload.to_bytes()))
                while (e := evs.try_recv()) is not None:
                    events = _latest_events(events, _event_line(json.loads(e.payload.to_bytes())))
                if now - t_draw >= 0.5:
                    rows = tally.rows(n_draw, now - t_draw)
                    n_draw, t_draw = tally.counts(), now
                    _draw(rig, rows, events, redraw)
                if args.duration is not None and now - t0 >= args.duration:
                    break
                time.sleep(0.02)
        except KeyboardInterrupt:
            pass
        if tally.total == 0:
            raise NoDaemon(f"no state received on {keys.state_all} (is the daemon running "
                           "with telemetry on?)")
    return 0


def _draw(rig: str, rows: list[tuple[str, ...]], events: list[str], redraw: bool) -> None:
    widths = [max(len(c), *(len(r[i]) for r in rows)) if rows else len(c)
              for i, c in enumerate(COLUMNS)]
    out = []
    if redraw:
        out.append("\x1b[H\x1b[2J")
    out.append(f"pamd watch: rig {rig}  ({time.strftime('%H:%M:%S')})")
    out.append("  ".join(c.rjust(w) for c, w in zip(COLUMNS, widths, strict=True)))
    for r in rows:
        out.append("  ".join(v.rjust(w) for v, w in zip(r, widths, strict=True)))
    if not rows:
        out.append("(no state yet)")
    out.extend(f"  {e}" for e in events)
    print("\n".join(out), flush=True)
