"""`pamd run`: run the rig (default: the built-in simulated rig) until the duration
is reached, the profile has finished, or Ctrl-C / SIGTERM; then reach the safe state
and print the run summary."""

from __future__ import annotations

import argparse
import json
import logging
import math
import re
import shlex
import signal
import sys
import threading
from types import FrameType

from pamd.client.cli.numbers import number
from pamd.client.cli.run_start import StartRequests
from pamd.config import load_config
from pamd.config.control_schema import OFF_DATA_POLICIES
from pamd.config.loader import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.daemon.service.notify import Notifier
from pamd.daemon.service.restart import restart_in_place, run_argv, unblock_signals
from pamd.iohost.viewer_spec import parse_listen
from pamd.loop.control.feedforward import LoadedModel, load_models
from pamd.loop.control.length_targets import check_length_profile_config
from pamd.loop.control.onoff import POSITION_TAKES_NO_MODEL
from pamd.profiles import SHAPE_NAMES, ProfileSpec, shapes_reading
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused, ConfigError, ConfigIssue
from pamd.wire.net_spec import TelemetryRequest
from pamd.wire.shape_names import SHAPE_PARAMS
from pamd.wire.verbs.table import parse_command

log = logging.getLogger("pamd")

#: where an interactive run records when nothing else is said, and its size cap
DEFAULT_RECORD_DIR = "runs"
DEFAULT_RECORD_MAX_MB = 500.0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "run", help="run the rig (default: the simulated rig)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run the fixed-rate control loop. With no --config, the built-in "
        "simulated DMSP-20 rig (config/sim.yaml).\n\n"
        "Start-up reads every sensor before writing anything, then holds the measured "
        "pressure. A run ends when --duration is reached, when the --profile has "
        "finished its cycles, or on Ctrl-C / SIGTERM; it then ramps to the safe state "
        "(the load-dependent safe pressure) and prints a summary.\n\n"
        "A fault (or an emergency stop) puts the rig in its safe state. A run with an end "
        "of its own (--duration, --cycles) then ends by itself once every valve command "
        "is at its safe pressure, with the fault in the summary and exit code 1 "
        "(--stay-on-fault: hold the safe state until a reset or a signal). An open-ended "
        "run, as the service runs, stays up for a reset (--end-on-fault: end as well).\n\n"
        "In a terminal a run records by default (MCAP, into ./runs, at most "
        f"{DEFAULT_RECORD_MAX_MB:g} MB a run) and ends naming the file and what to do with "
        "it; --no-record skips that. Otherwise (a service, a script) it records as the "
        "config's recording section says, or with --record.\n\n"
        "A virtual-clock run is a private simulation: no lock, no state, no port unless "
        "--listen asks for one. A "
        "real-clock run locks what it opens (its serial ports, fieldbus devices, CAN "
        "channels, state directory), so a second daemon on them is refused naming the "
        "first.",
        epilog="examples:\n"
        "  pamd run --clock virtual --profile sine --cycles 2      # the seeds' sweep\n"
        "  pamd run --profile sine --freq-hz 0.05 --min-bar 0 --max-bar 6 --cycles 2\n"
        "  pamd run --config rig.yaml --duration 60 --json\n"
        "  pamd run --listen tcp/127.0.0.1:7448      # beside a daemon on the default port")
    p.add_argument("--config", metavar="FILE", help="rig config (default: built-in sim)")
    p.add_argument("--clock", choices=("real", "virtual"),
                   help="override loop.clock (virtual: as fast as possible, deterministic)")
    p.add_argument("--rate-hz", type=number("Hz", gt=0.0), help="override loop.rate_hz")
    p.add_argument("--duration", type=number("s", gt=0.0), metavar="S",
                   help="stop after S seconds (at most 30 days)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.add_argument("--note", default="", help="operator note kept with the run")
    p.add_argument("--load-kg", metavar="[MUSCLE=]KG", action="append", type=_load_kg,
                   help="the load hanging on the muscle for this run, in place of its "
                   "load_kg (which sets the safe pressure); MUSCLE=KG for each muscle of "
                   "a rig with several (repeat it, or m1=30,m2=20). Checked like the "
                   "config's: within the muscle's rating, and before anything moves the "
                   "force at rest must read its weight (a disagreement refuses a run "
                   "with an end, exit 2, naming both loads)")
    f = p.add_mutually_exclusive_group()
    f.add_argument("--stay-on-fault", action="store_true", help="a run with an end of its "
                   "own (--duration, --cycles) that faults holds its safe state until a "
                   "reset or a signal (default: it ends once the safe state holds, exit 1)")
    f.add_argument("--end-on-fault", action="store_true", help="an open-ended run (no "
                   "--duration or --cycles, as the service runs) ends once the safe state "
                   "of a fault holds, exit 1 (default: it stays up for a reset)")
    p.add_argument("--state-dir", metavar="DIR", help="keep the latched fault, the safe "
                   "outputs and the home/tare datums in DIR (overrides state_dir of the "
                   "config; default: ~/.local/state/pamd/<rig_id> for a real-clock run of "
                   "a config, none for a virtual-clock run or the built-in sim; the service "
                   "uses /var/lib/pamd)")
    r = p.add_argument_group("recording (MCAP, written by the io process)")
    r.add_argument("--record", metavar="DIR", nargs="?", const="", help="record the run "
                   "into DIR (overrides recording.dir of the config; without DIR: the "
                   "config's recording.dir, else ./runs)")
    r.add_argument("--no-record", action="store_true", help="do not record, even in a "
                   "terminal or if the config names a directory")
    r.add_argument("--name", help="run name in the file name (default: recording.run_name)")
    t = p.add_argument_group("telemetry and remote commands (Zenoh, in the io process)")
    t.add_argument("--no-telemetry", action="store_true", help="no Zenoh session: no state, "
                   "status or remote commands (default: as telemetry.enabled says, on)")
    t.add_argument("--listen", metavar="ENDPOINT", type=_endpoint, help="where the "
                   "daemon's Zenoh session listens, e.g. tcp/127.0.0.1:7448 (overrides "
                   "telemetry.listen and a Zenoh config's listen endpoints; turns telemetry "
                   "on, with the virtual clock too); clients reach it with --connect")
    t.add_argument("--allow-cleartext", action="store_true", help="let the Zenoh session "
                   "listen on or connect to an endpoint beyond loopback without TLS (e.g. "
                   "--listen tcp/0.0.0.0:7447, a Zenoh config connecting to "
                   "tcp/<router>:7447) and the Foxglove view serve there without TLS "
                   "(--foxglove 0.0.0.0:8765): refused otherwise, since state, status and "
                   "commands then cross the network in clear; warned at start and in every "
                   "status (as telemetry.allow_cleartext: true)")
    t.add_argument("--zenoh-config", metavar="FILE", help="Zenoh config (JSON5) of the "
                   "daemon's session (overrides telemetry.zenoh_config; default: listen on "
                   "telemetry.listen, tcp/127.0.0.1:7447)")
    t.add_argument("--foxglove", nargs="?", const="default", metavar="HOST:PORT",
                   type=_listen, help="serve a live view to Foxglove (WebSocket, in the io "
                   "process; a viewer, commands stay on Zenoh) on HOST:PORT (default: "
                   "telemetry.foxglove.listen, 127.0.0.1:8765); beyond loopback it needs "
                   "telemetry.foxglove.tls_cert/tls_key (wss://) or --allow-cleartext; "
                   "layout: config/foxglove/pamd-layout.json")
    g = p.add_argument_group("profile (on every muscle unless --muscle)")
    g.add_argument("--profile", choices=SHAPE_NAMES, help="start this profile")
    g.add_argument("--muscle", help="apply the profile to this muscle only")
    g.add_argument("--freq-hz", type=float,
                   help=f"{shapes_reading('freq_hz', '/')} (0.05); in a length mode too")
    g.add_argument("--min-bar", type=float, help="lowest pressure (0)")
    g.add_argument("--max-bar", type=float, help="highest pressure (6)")
    g.add_argument("--cycles", type=int, help=f"number of cycles ({shapes_reading('cycles', '/')}; "
                   "default: until stopped)")
    g.add_argument("--to-bar", type=float, help=f"{shapes_reading('to_bar', '/')} target")
    g.add_argument("--rate-bar-per-s", type=float, help="ramp rate (pressure mode; a "
                   "length ramp runs at half control.position.max_rate_per_s)")
    lm = p.add_argument_group(
        "length modes (the ANFIS inverse model as feedforward; every muscle unless --muscle)")
    lm.add_argument("--mode", choices=("pressure", "length_force", "position"),
                    help="control mode from the start (length modes need a length "
                    "with its datum and, but for position --no-feedforward, a model); a --profile "
                    "is then a length profile in contraction")
    lm.add_argument("--model", metavar="FILE", help="inverse model (pamd train) for the "
                    "length modes, overriding model_file of the config; read and checked "
                    "before anything starts")
    lm.add_argument("--no-feedforward", action="store_true",
                    help="position mode with the position PID alone (no model)")
    lm.add_argument("--off-data", choices=OFF_DATA_POLICIES,
                    help="when the model's inputs leave its training domain (a force beyond "
                    "its trained loads, a length or pressure not seen at that force; a load "
                    "between two trained loads is inside): fade its feedforward to the "
                    "position PID alone there and back (fade), only say it (warn), or do not "
                    "judge (off); overrides control.feedforward.off_data (default fade). "
                    "The summary's feedforward line says how often")
    lm.add_argument("--ilc", action="store_true", help="position mode: iterative learning "
                    "over the cycles of a periodic length profile")
    lm.add_argument("--min-contraction", type=float, help="length profile: least "
                    "contraction (fraction, e.g. 0.05)")
    lm.add_argument("--max-contraction", type=float, help="length profile: most contraction "
                    "(fraction, e.g. 0.20)")
    lm.add_argument("--to-contraction", type=float, help="length profile: "
                    f"{shapes_reading('to_bar', '/')} target (fraction)")
    p.set_defaults(func=run)


def _load_kg(text: str) -> list[tuple[str | None, float]]:
    """--load-kg's KG or MUSCLE=KG[,MUSCLE=KG...], each a finite mass of 0 kg or more;
    which muscles there are and their ratings are checked once the config is read."""
    out: list[tuple[str | None, float]] = []
    for part in text.split(","):
        name, sep, value = part.strip().rpartition("=")
        try:
            kg = float(value)
        except ValueError:
            kg = math.nan
        if not (math.isfinite(kg) and kg >= 0.0) or (sep and not name):
            raise argparse.ArgumentTypeError(
                f"{part.strip()!r}: expected KG or MUSCLE=KG, a mass of 0 kg or more "
                "(e.g. 30, or m1=30)")
        out.append((name or None, kg))
    return out


def load_overrides(given: list[list[tuple[str | None, float]]] | None,
                   cfg: LoadedConfig) -> JsonObject:
    """--load-kg as config overrides (`{"m1": {"load_kg": 30.0}}`), checked like the
    config's load_kg: a muscle the config has, within its rating; a bare KG only for a
    rig of one muscle. Refused (ConfigError, exit 2) naming --load-kg."""
    out: JsonObject = {}
    names = [m.name for m in cfg.rig.muscles]
    issues = []
    for name, kg in (pair for group in given or [] for pair in group):
        if name is None and len(names) > 1:
            issues.append(ConfigIssue("--load-kg", None, "", f"MUSCLE=KG for one of "
                                      f"{', '.join(names)} (this rig has several muscles)",
                                      f"{kg:g}"))
            continue
        name = name or names[0]
        if name not in names:
            issues.append(ConfigIssue("--load-kg", None, name, f"one of the config's "
                                      f"muscles ({', '.join(names)})", repr(name)))
            continue
        m = cfg.muscle(name)
        rated = cfg.muscle_type(name).max_load_kg
        if kg > rated:
            issues.append(ConfigIssue("--load-kg", None, name, f"at most {rated} kg "
                                      f"({m.type} rating)", f"{kg:g} kg"))
        out[name] = {"load_kg": kg}
    if issues:
        raise ConfigError(issues)
    return out


def _endpoint(text: str) -> str:
    """--listen's Zenoh endpoint, checked before anything starts."""
    if not re.fullmatch(r"[a-z0-9]+/(\[[0-9A-Fa-f:.]+\]|[^/:\s]+):\d{1,5}(#\S*)?", text):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a Zenoh endpoint: PROTOCOL/HOST:PORT, e.g. tcp/127.0.0.1:7448")
    port = int(text.split("#", 1)[0].rsplit(":", 1)[1])
    if not 0 < port < 65536:
        raise argparse.ArgumentTypeError(f"{text!r}: port {port} is not 1-65535")
    return text


def _listen(text: str) -> str:
    """--foxglove's HOST:PORT, checked before anything starts."""

    if text == "default":
        return text
    try:
        parse_listen(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


#: The profile options of each mode: ProfileSpec's parameter -> the option that gives
#: it (a length profile's "bar" fields hold contraction: `length_profile`).
PRESSURE_OPTIONS = {"min_bar": "--min-bar", "max_bar": "--max-bar", "freq_hz": "--freq-hz",
                    "cycles": "--cycles", "to_bar": "--to-bar",
                    "rate_bar_per_s": "--rate-bar-per-s"}
LENGTH_OPTIONS = {"min_bar": "--min-contraction", "max_bar": "--max-contraction",
                  "freq_hz": "--freq-hz", "cycles": "--cycles", "to_bar": "--to-contraction"}
#: each option's field of the `profile` command in a length mode
LENGTH_FIELDS = {"--min-contraction": "min_contraction", "--max-contraction": "max_contraction",
                 "--to-contraction": "to_contraction", "--freq-hz": "freq_hz",
                 "--cycles": "cycles"}


def _dest(option: str) -> str:
    return option[2:].replace("-", "_")


def _profile_options(args: argparse.Namespace, length_mode: bool) -> dict[str, str]:
    """The profile options given (ProfileSpec parameter -> option), each one the mode
    and the shape read; a given option either does not read is refused, not ignored
    (a length profile never reads --rate-bar-per-s; a constant never reads
    --freq-hz), as a profile parameter its shape does not read is
    (`ProfileSpec.check_reads`)."""
    mine, other = ((LENGTH_OPTIONS, PRESSURE_OPTIONS) if length_mode else
                   (PRESSURE_OPTIONS, LENGTH_OPTIONS))
    given = {o for o in {*mine.values(), *other.values()} if getattr(args, _dest(o)) is not None}
    _refuse_other_mode(args, length_mode, mine, given)
    if args.profile is None:
        if given:
            raise CommandRefused(f"{' and '.join(sorted(given))} without --profile: name the "
                                 "profile they shape (--profile sine, ...)")
        return {}
    _refuse_unread(args.profile, mine, given)
    return {p: o for p, o in mine.items() if o in given}


def _refuse_other_mode(args: argparse.Namespace, length_mode: bool, mine: dict[str, str],
                       given: set[str]) -> None:
    """Refused: a profile option given that only the other mode's profiles read."""
    wrong_mode = sorted(given - set(mine.values()))
    if not wrong_mode:
        return
    which = "a length profile (--mode position or length_force)" if not length_mode \
        else "a pressure profile"
    reads = ", ".join(dict.fromkeys(mine.values()))
    raise CommandRefused(
        f"{' and '.join(wrong_mode)}: {'these are' if len(wrong_mode) > 1 else 'this is'} "
        f"{which}'s; {'--mode ' + args.mode if length_mode else 'the pressure mode'} "
        f"reads {reads}")


def _refuse_unread(profile: str, mine: dict[str, str], given: set[str]) -> None:
    """Refused: a profile option given that the profile's shape does not read."""
    shape_reads = set(SHAPE_PARAMS[profile])
    unread = sorted(o for p, o in mine.items() if o in given and p not in shape_reads)
    if not unread:
        return
    wanted = [mine[p] for p in SHAPE_PARAMS[profile] if p in mine]
    raise CommandRefused(
        f"--profile {profile} does not read {' or '.join(unread)} (it reads "
        f"{', '.join(wanted) or 'none of them'}); leave "
        f"{'them' if len(unread) > 1 else 'it'} out" + (
            "; a constant holds until stopped, or for the run's --duration"
            if profile == "constant" else ""))


def _checked(verb: str, payload: JsonObject, option_of: dict[str, str]) -> None:
    """`payload` as the daemon would parse the command (`pamd.wire.verbs`: types, each
    number finite, of a physical size and inside its unit's domain), before anything
    opens: a refusal names the option (`option_of`: field -> option)."""
    parse_command(verb, payload, label=lambda field: option_of.get(field, field))


def _pressure_profile(args: argparse.Namespace, cfg: LoadedConfig,
                      given: dict[str, str]) -> JsonObject:
    """The --profile of the pressure mode as a profile command, checked against each
    selected muscle's limits and the slew limit before anything opens."""
    numbers: JsonObject = {p: getattr(args, _dest(o)) for p, o in given.items()}
    payload: JsonObject = {"shape": args.profile, **numbers}
    _checked("profile", payload, {p: o for p, o in PRESSURE_OPTIONS.items()})
    spec = ProfileSpec(shape_name=args.profile, **numbers)
    for m in cfg.rig.muscles:
        if args.muscle in (None, m.name):
            spec.check(0.0, cfg.limits[m.name].max_pressure_bar,
                       cfg.rig.control.slew_limit_bar_per_s, cfg.period_s)
    if args.muscle:
        payload["muscle"] = args.muscle
    return payload


def _models(cfg: LoadedConfig, args: argparse.Namespace
            ) -> tuple[dict[str, LoadedModel], str | None]:
    """The config's model files and --model, read and checked for the selected muscles
    (an error before anything opens); returns each muscle's model and the model file to
    attach to a recording."""
    models = load_models(cfg)
    names = [m.name for m in cfg.rig.muscles if args.muscle in (None, m.name)]
    if args.model is not None:
        models |= {n: LoadedModel.read(args.model, cfg.muscle(n), cfg.limits[n])
                   for n in names}
    chosen = [models[n] for n in names if n in models]
    for note in sorted({n for m in chosen for n in m.notes()}):  # an older file's lack
        log.warning("pamd run: %s", note)
    return models, args.model if args.model is not None else (
        chosen[0].path if chosen else None)


def _length_profile(args: argparse.Namespace, cfg: LoadedConfig,
                    given: dict[str, str]) -> JsonObject:
    """The --profile of a length mode as a profile command (contraction), checked
    against each muscle's limits, load and rate limit before anything opens."""

    payload: JsonObject = {"shape": args.profile,
                           **{LENGTH_FIELDS[o]: getattr(args, _dest(o)) for o in given.values()}}
    _checked("profile", payload, {f: o for o, f in LENGTH_FIELDS.items()})
    for m in cfg.rig.muscles:
        if args.muscle in (None, m.name):
            check_length_profile_config(cfg, m.name, payload)
    if args.muscle:
        payload["muscle"] = args.muscle
    return payload


def interactive() -> bool:
    """A person at a terminal ran this (not the service, not a script's pipe)."""
    return sys.stdout.isatty()


def record_where(args: argparse.Namespace, cfg: LoadedConfig
                  ) -> tuple[str | None, float | None]:
    """Where this run records (None: not at all) and its size cap: --no-record;
    --record DIR; --record alone: the config's dir, else ./runs; else the config's
    recording.dir (the service's own settings, uncapped); else, in a terminal, ./runs
    capped at DEFAULT_RECORD_MAX_MB."""
    if args.no_record:
        return None, None
    configured = cfg.rig.recording.dir
    if args.record:
        return args.record, None
    if args.record == "" or configured:
        return configured or DEFAULT_RECORD_DIR, None
    if interactive():
        return DEFAULT_RECORD_DIR, DEFAULT_RECORD_MAX_MB
    return None, None


def not_recording_why(args: argparse.Namespace) -> str:
    """Why a run records nothing (`record_where` gave no directory), and how it would."""
    if args.no_record:
        return "--no-record"
    return ("its output is not a terminal (a script, a service, a pipe such as `| tee`), "
            "where a run records only when told: --record [DIR], or the config's "
            "recording.dir")


def run(args: argparse.Namespace) -> int:
    overrides = _overrides(args)
    cfg = load_config(args.config, overrides)
    if args.load_kg:  # for this run (and its reloads), checked against the ratings first
        overrides["muscles"] = load_overrides(args.load_kg, cfg)
        cfg = load_config(args.config, overrides)
    models, model_path = _models(cfg, args)
    profile = _start_profile(args, cfg, models)  # refused before anything opens or moves
    if args.listen and args.no_telemetry:
        raise CommandRefused("--listen is where telemetry listens: it goes without "
                             "--no-telemetry")
    record_dir, max_mb = record_where(args, cfg)
    recording = RecordingRequest(dir=record_dir, enabled=record_dir is not None,
                                 run_name=args.name, profile=profile, model_path=model_path,
                                 max_mb=max_mb)
    telemetry = TelemetryRequest(enabled=not args.no_telemetry, zenoh_config=args.zenoh_config,
                                 foxglove=args.foxglove, listen=args.listen,
                                 allow_cleartext=args.allow_cleartext)
    daemon = Daemon(cfg, note=args.note, recording=recording, state_dir=args.state_dir,
                    models=models,
                    notifier=Notifier.from_environ(), config_overrides=overrides,
                    telemetry=telemetry)
    daemon.keeper.allow_restart_in_place()  # a reload that reopens the devices execs again
    signalled = _install_signals(daemon)
    start = StartRequests(daemon, _start_requests(args, profile),
                          loads_given=overrides.get("muscles") or {})
    daemon.start(args.duration, stop_when_profile_done=profile is not None and
                 args.cycles is not None, end_on_fault=_end_on_fault(args))
    _say_recording(args, cfg, record_dir, max_mb)
    try:
        start.send(cfg.rig.safety.startup_timeout_s + 5.0)
        daemon.wait()
        start.refuse_wrong_load()  # a run that ended in start-up (no request waited)
    finally:
        daemon.stop("shutting down")
        daemon.wait()
        daemon.close()
    return _finish(args, cfg, daemon, signalled)


def _overrides(args: argparse.Namespace) -> JsonObject:
    """The config's values this run's options override (--clock, --rate-hz,
    --off-data)."""
    overrides: JsonObject = {}
    if args.clock:
        overrides.setdefault("loop", {})["clock"] = args.clock
    if args.rate_hz is not None:
        overrides.setdefault("loop", {})["rate_hz"] = args.rate_hz
    if args.off_data:
        overrides.setdefault("control", {})["feedforward"] = {"off_data": args.off_data}
    return overrides


def _start_profile(args: argparse.Namespace, cfg: LoadedConfig,
                   models: dict[str, LoadedModel]) -> JsonObject | None:
    """The --profile as the profile command sent at the start (None: no profile), its
    options, the --mode's model and the profile checked before anything opens."""
    length_mode = args.mode in ("length_force", "position")
    given = _profile_options(args, length_mode)  # before any file is read
    _check_mode_models(args, cfg, models)
    if args.profile is None:
        return None
    return (_length_profile(args, cfg, given) if length_mode else
            _pressure_profile(args, cfg, given))


def _check_mode_models(args: argparse.Namespace, cfg: LoadedConfig,
                       models: dict[str, LoadedModel]) -> None:
    """Each selected muscle has a model where --mode needs one, and takes one: an on/off
    muscle's position mode runs without."""
    needs_model = args.mode == "length_force" or (args.mode == "position"
                                                  and not args.no_feedforward)
    for m in cfg.rig.muscles:
        if (args.mode == "position" and not args.no_feedforward and m.actuation == "onoff"
                and args.muscle in (None, m.name)):
            raise CommandRefused(f"{m.name}: --mode position with a model: "
                                 f"{POSITION_TAKES_NO_MODEL}")
        if needs_model and args.muscle in (None, m.name) and m.name not in models:
            raise CommandRefused(f"{m.name}: --mode {args.mode} needs a model: --model FILE "
                                 "or model_file in the config (position mode runs without "
                                 "one with --no-feedforward)")


def _start_requests(args: argparse.Namespace, profile: JsonObject | None
                    ) -> list[tuple[str, JsonObject]]:
    """The commands sent once the start-up is over and its ramp (a muscle that started
    outside its limits) has ended; on the virtual clock at a standstill, so a virtual
    run is the same every time (pamd.client.cli.run_start): --mode, then --profile."""
    requests: list[tuple[str, JsonObject]] = []
    if args.mode is not None:  # before the profile: both land on the same tick
        mode_args: JsonObject = {"mode": args.mode, "feedforward": not args.no_feedforward,
                                 "ilc": args.ilc}
        if args.muscle:
            mode_args["muscle"] = args.muscle
        requests.append(("mode", mode_args))
    if profile is not None:
        requests.append(("profile", profile))
    return requests


def _say_recording(args: argparse.Namespace, cfg: LoadedConfig, record_dir: str | None,
                   max_mb: float | None) -> None:
    """Where the run records, or why it does not; that a virtual run without end runs
    until stopped."""
    if record_dir is not None and not args.json:
        cap = f", at most {max_mb:g} MB" if max_mb else ""
        log.info("recording into %s%s (--no-record: none)", record_dir, cap)
    if record_dir is None:  # always said: a run nobody can open afterwards is a surprise
        log.info("not recording: %s", not_recording_why(args))
    if cfg.rig.loop.clock == "virtual" and args.duration is None and args.cycles is None:
        log.info("virtual clock with no end (no --duration, no --cycles): the simulation "
                 "runs as fast as it can until Ctrl-C or SIGTERM")


def _finish(args: argparse.Namespace, cfg: LoadedConfig, daemon: Daemon,
            signalled: list[str]) -> int:
    """After the run: a restart in place where a reload handed the outputs over, the
    result printed (summary or JSON), the exit code."""
    result = daemon.result()
    if daemon.loop.handed_over and daemon.error is None:
        # the outputs hold: the new daemon must take over (and, with no time left
        # of --duration, read, then stop to the safe state at once)
        remaining = (None if args.duration is None else
                     max(args.duration - result["duration_s"], cfg.period_s))
        if not args.json:
            print_summary(result)
        restart_in_place(run_argv(args, remaining), daemon.keeper.handover or "",
                         stop_received=bool(signalled))
    if daemon.error is not None:
        result["faults"].append(f"loop crashed: {daemon.error!r}")
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print_summary(result)
    if daemon.error is not None:
        return 1
    if signalled and daemon.ctrl.at_safe_state():
        # Stopped on purpose and safe: a latched fault stays in the summary and in the
        # state directory (the next start comes back latched), not in the exit code,
        # so systemd does not count a clean stop as a failure.
        return 0
    return 1 if result["final_state"] in ("FAULT", "ESTOP") else 0


def _end_on_fault(args: argparse.Namespace) -> bool:
    """Whether a latched fault ends the run: by default a run with an end of its own
    (--duration, --cycles: a script waits for it) ends once its safe state holds; an
    open-ended one (the service, a rig driven by remote commands) stays up for a reset."""
    if args.stay_on_fault or args.end_on_fault:
        return bool(args.end_on_fault)
    return args.duration is not None or args.cycles is not None


def _install_signals(daemon: Daemon) -> list[str]:
    """SIGTERM/SIGINT: safe state, finalise, exit. SIGHUP: reload the config. Returns
    the list the handler appends the names of the stop signals it received to."""
    received: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        return received

    def handler(signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        received.append(name)
        daemon.stop(f"{name} received")

    def reload(signum: int, frame: FrameType | None) -> None:
        daemon.request_reload()  # done by daemon.service(), in this (main) thread

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGHUP, reload)
    if signal.SIGHUP in signal.sigpending():  # held since `pamd.client.cli.main.main`
        log.warning("SIGHUP during start-up: queued; the config is read again once the "
                    "rig has started")
    unblock_signals()  # what the start (or a restart in place) held back for this daemon
    return received


def print_summary(r: JsonObject) -> None:
    out = sys.stdout
    w, c = r["wake_latency_us"], r["compute_us"]
    loads = ", ".join(f"{m} {kg:g} kg" for m, kg in r.get("loads_kg", {}).items())
    print(f"pamd run: {r['ticks']} ticks ({r['duration_s']:.1f} s, {r['clock']} clock at "
          f"{r['rate_hz']:g} Hz), stopped: {r['stop_reason'] or 'n/a'}", file=out)
    if loads:
        print(f"  load: {loads}", file=out)
    print(f"  overruns {r['overruns']}, lost records {r['lost_records']}", file=out)
    print(f"  wake-up latency p50 {w['p50']:.0f} us, p99 {w['p99']:.0f} us, max "
          f"{w['max']:.0f} us", file=out)
    print(f"  compute time    p50 {c['p50']:.0f} us, p99 {c['p99']:.0f} us, max "
          f"{c['max']:.0f} us", file=out)
    for name, t in r["tracking"].items():
        for line in _tracking_lines(name, t):
            print(line, file=out)
    for line in _feedforward_lines(r):
        print(line, file=out)
    for line in _switching_lines(r):
        print(line, file=out)
    rec = r.get("recording")
    if rec:
        for line in _recording_lines(rec, r["ticks"]):
            print(line, file=out)
    for line in _exit_lines(r):
        print(line, file=out)
    if rec and rec["files"]:
        print(next_steps(rec["files"]), file=out)


def _tracking_lines(name: str, t: JsonObject) -> list[str]:
    """The summary's lines on a muscle's tracking: pressure and length, over the run and
    after the first cycle, and the time a soft limit held it back."""
    if not (t["samples"] or t.get("length_samples")):
        return [f"  {name}: no profile ran (no tracking figures)"]
    lines = []
    if t["samples"]:  # none where no pressure setpoint ran (on/off positioning)
        lines.append(f"  {name}: pressure tracking RMSE {t['rmse_bar']:.4f} bar, MAE "
                     f"{t['mae_bar']:.4f} bar, max error "
                     f"{t['max_error_bar']:.4f} bar ({t['samples']} ticks running)")
    if t.get("samples_after_first_cycle"):
        lines.append(f"  {name}:   after the first cycle: RMSE "
                     f"{t['rmse_bar_after_first_cycle']:.4f} bar, MAE "
                     f"{t['mae_bar_after_first_cycle']:.4f} bar, max error "
                     f"{t['max_error_bar_after_first_cycle']:.4f} bar "
                     f"({t['samples_after_first_cycle']} ticks)")
    if t.get("length_samples"):
        lines.append(f"  {name}: length tracking RMSE {t['length_rmse_mm']:.3f} mm, MAE "
                     f"{t['length_mae_mm']:.3f} mm, max "
                     f"error {t['length_max_error_mm']:.3f} mm ({t['length_samples']} "
                     "ticks with a length target)")
    if t.get("length_samples_after_first_cycle"):
        lines.append(f"  {name}:   after the first cycle: RMSE "
                     f"{t['length_rmse_mm_after_first_cycle']:.3f} mm, MAE "
                     f"{t['length_mae_mm_after_first_cycle']:.3f} mm, max error "
                     f"{t['length_max_error_mm_after_first_cycle']:.3f} mm "
                     f"({t['length_samples_after_first_cycle']} ticks)")
    if t.get("soft_limit_s"):
        lines.append(f"  {name}: held back by a soft limit for {t['soft_limit_s']:.1f} s "
                     f"while running ({t['soft_limit_events']} time(s) over 1 s): the "
                     "profile was not followed there")
    return lines


def _feedforward_lines(r: JsonObject) -> list[str]:
    """The summary's line on each muscle's model feedforward (none where no model ran)."""
    lines = []
    for name, ff in (r.get("feedforward") or {}).items():
        line = feedforward_line(ff)
        if line:
            lines.append(f"  {name}: {line}")
    return lines


def _switching_lines(r: JsonObject) -> list[str]:
    """The summary's line on each muscle's valve switchings (on/off valves), with their
    rates over the run."""
    lines = []
    for name, sw in r.get("valve_switches", {}).items():
        if sw:
            per_s = r["duration_s"] or 1.0
            lines.append(f"  {name}: valve switchings "
                         + ", ".join(f"{v} {n} ({n / per_s:.1f}/s)" for v, n in sw.items()))
    return lines


def _exit_lines(r: JsonObject) -> list[str]:
    """The summary's lines on how the run ended: its faults, the outputs at exit, the
    final state."""
    faults = r["faults"]
    lines = [f"  faults: {'; '.join(faults) if faults else 'none'}"]
    outputs = r.get("outputs") or {}
    if outputs:
        lines.append("  outputs at exit: " + ", ".join(
            f"{n} {o['valve_cmd_bar']:.2f} bar (safe pressure {o['safe_pressure_bar']:.2f})"
            for n, o in outputs.items()))
    lines.append(f"  final state: {r['final_state']}")
    return lines


def _recording_lines(rec: JsonObject, ticks: int) -> list[str]:
    """The summary's lines on the recording: its files and counts, a size cap that
    stopped it before the run's `ticks` were in, a failure."""
    files = ", ".join(rec["files"]) or "none"
    lines = [f"  recording: {files} ({rec['ticks_recorded']} ticks, lost records "
             f"{rec['lost_records']}, lost events {rec['lost_events']})"]
    cap = rec.get("max_mb")
    if cap and rec["ticks_recorded"] + rec["lost_records"] < ticks:
        lines.append(f"  recording stopped at its size cap of {cap:g} MB (the run's later "
                     "ticks are not in it): --record DIR records a run whole")
    if rec.get("failure"):
        lines.append(f"  recording FAILED: {rec['failure']['reason']} "
                     f"({rec['failure']['policy']})")
    return lines


def feedforward_line(ff: JsonObject) -> str:
    """The summary's line on a muscle's feedforward (none where no model ran)."""
    if not ff.get("ticks"):
        return ""
    parts = []
    if ff.get("off_data_pct") is not None:
        parts.append(f"off its training data {ff['off_data_pct']:.1f} % of the running "
                     f"ticks, faded {ff['faded_pct']:.1f} % (off_data: {ff['off_data']})")
    else:
        parts.append("off its training data: not judged (off_data: off)")
    if ff.get("oscillations"):
        parts.append(f"OSCILLATING against the pressure loop {ff['oscillating_pct']:.1f} % "
                     f"of the running ticks ({ff['oscillations']} time(s))")
    return "model feedforward " + "; ".join(parts)


def next_steps(files: list[str]) -> str:
    """What to do with the run's recording: the commands, with its file."""
    first = shlex.quote(files[0])
    return (f"next: pamd inspect {first}    # what it holds\n"
            f"      pamd plot {first}       # pressure, length, force (PNG)\n"
            f"      pamd export {first} --csv DIR   # tables for a spreadsheet")
