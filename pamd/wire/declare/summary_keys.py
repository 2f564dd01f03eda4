"""The run summary's keys, declared once: what `pamd run --json` prints, the daemon's
`result()` returns and the recording's `pamd.summary` metadata holds
(`pamd.daemon.daemon.Daemon.result` builds it; a test runs a virtual run and compares its keys
with these). docs/run-summary.md is generated from this table:
``python -m pamd.wire.declare.summary_keys > docs/run-summary.md``."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SummaryKey:
    """One top-level key of the run summary and what it holds."""

    name: str
    meaning: str


SUMMARY: tuple[SummaryKey, ...] = (
    SummaryKey("rig_id", "what ran: the config's rig id"),
    SummaryKey("clock", "what ran: the loop's clock, real, virtual or daq"),
    SummaryKey("rate_hz", "what ran: the loop's rate"),
    SummaryKey("ticks", "ticks run"),
    SummaryKey("duration_s", "the ticks' span in rig time"),
    SummaryKey("overruns", "periods skipped because a tick was late"),
    SummaryKey("stalls", "`count` and `longest_ms` of the stalls (gaps over "
               "`loop.stall_timeout_s` with no tick completed; each also a `stall` event and "
               "a warning), `timeout_ms`, and `fault_ms` with `why`: the stall that latches "
               "FAULT ([safety checks](explanation/safety-checks.md), \"A stalled loop\")"),
    SummaryKey("lost_records", "tick records the recorder could not take"),
    SummaryKey("wake_latency_us", "`p50`, `p99`, `max`: how late the loop woke (0 with the "
               "virtual clock; with the daq clock, after the sample clock's edge)"),
    SummaryKey("compute_us", "`p50`, `p99`, `max`: time spent in a tick"),
    SummaryKey("loads_kg", "per muscle, the load hanging at the end (the summary's `load:` "
               "line)"),
    SummaryKey("tracking", "per muscle: `rmse_bar`, `mae_bar`, `max_error_bar` of measured "
               "pressure vs the profile's target (the setpoint, which no limit ever clamps: a "
               "profile a limit holds back shows as error) while RUNNING, and `samples`; in "
               "the length modes also `length_rmse_mm`, `length_mae_mm`, "
               "`length_max_error_mm` of measured vs target length and `length_samples` "
               "(None and 0 otherwise); the same after the profile's first cycle (its lead-in "
               "and first cycle left out, the span of the tracking figures in these docs and "
               "in bench/), with the suffix `_after_first_cycle` (None for a profile of one "
               "cycle); `soft_limit_s`, how long a soft limit held the command back while "
               "RUNNING, and `soft_limit_events`, how often that lasted over 1 s (each also a "
               "`soft_limit` event)"),
    SummaryKey("feedforward", "per muscle, the model's watch while RUNNING with it in use "
               "(`ticks`): `off_data` (the policy, `control.feedforward.off_data`), "
               "`off_data_pct` (its inputs off its training domain), `faded_pct` (its "
               "feedforward faded toward the PID alone), `oscillating_pct` and `oscillations` "
               "(against the pressure loop); the shares null where nothing was judged. Also in "
               "the status, and as the summary's `model feedforward` line "
               "([the inverse model](explanation/inverse-model.md), \"Off its data in the "
               "loop\")"),
    SummaryKey("valve_switches", "per muscle, switchings per valve since start (`inflate`, "
               "`exhaust` on on/off valves; the exhaust valve's `exhaust` beside a regulator); "
               "also in the recording's `pamd.summary` metadata"),
    SummaryKey("faults", "every fault reason, in order"),
    SummaryKey("final_state", "supervisor state at exit (`IDLE` after a clean stop)"),
    SummaryKey("outputs", "per muscle, the `valve_cmd_bar` written last and its "
               "`safe_pressure_bar` (equal after a fault ended the run)"),
    SummaryKey("stop_reason", "`duration reached`, `profile finished`, `SIGTERM received`, "
               "`fault: <reason>` (a fault ended the run), ..."),
    SummaryKey("drivers", "per driver, its last 3 `errors` (naming device and channel) and "
               "its `counters`: requests and frames read, `timeouts`, `retries` (a lost reply "
               "re-sent), `failed_reads` (a frame that could not be read, skipped), "
               "`disconnects` / `bus_errors` (the link re-opened), `faults`: what a driver "
               "fault came from"),
    SummaryKey("realtime", "real-time settings `applied` and `refused` (with how to allow "
               "them)"),
    SummaryKey("recording", "`files`, `ticks_recorded`, `lost_records`, `lost_events`, "
               "`failure`, `max_mb` (the size cap, null for none); null when the run did not "
               "record"),
    SummaryKey("telemetry", "`rig_id`, `every_ticks` of the Zenoh session (null with "
               "`--no-telemetry`)"),
)

HEAD = """# The run summary (`pamd run --json`)

<!-- Generated by `python -m pamd.wire.declare.summary_keys > docs/run-summary.md` from
`pamd/wire/declare/summary_keys.py`; do not edit by hand. -->

What a run prints when it ends (`pamd run --json`: one JSON object with these keys, in
this order), what the daemon's `result()` returns and the recording's `pamd.summary`
metadata holds.

| key | meaning |
|---|---|
"""


def markdown() -> str:
    """The page."""
    return HEAD + "".join(f"| `{k.name}` | {k.meaning} |\n" for k in SUMMARY)


if __name__ == "__main__":
    print(markdown(), end="")
