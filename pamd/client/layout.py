"""The Foxglove layout of a rig: per muscle, pressure against setpoint and valve
command, length against target, force; the supervisor state and control modes over
time; the latest event. Its message paths name the recording's topics and fields, so
it shows a live rig (`pamd run --foxglove`) and a recorded file alike, with the log
time (the tick's) as the time axis.

config/foxglove/pamd-layout.json is this layout for the simulated rig (rig_id `sim`,
muscle `m1`); for another rig:

    python -m pamd.client.layout --config rig.yaml --out my-rig-layout.json

Import it in Foxglove: Layouts, Import from file.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from pamd.config import load_config
from pamd.wire.atomic import write_atomic
from pamd.wire.declare import fields
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.tick import Mode, State

#: the plot panels of a muscle's tab: title, y unit, series colours in order; the
#: series are the field table's fields with that `plot` (pamd.wire.declare.fields)
PANELS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "pressure": ("pressure vs setpoint, valve command", "bar",
                 ("#1f77b4", "#ff7f0e", "#7f7f7f", "#2ca02c")),
    "length": ("length vs target", "mm", ("#1f77b4", "#ff7f0e", "#7f7f7f")),
    "force": ("force", "N", ("#2ca02c", "#ff7f0e", "#7f7f7f")),
}

_COLORS = {"STARTING": "#9e9e9e", "IDLE": "#1f77b4", "RUNNING": "#2ca02c", "HOLD": "#ff7f0e",
           "FAULT": "#d62728", "ESTOP": "#7f0000", "LOAD_CHANGE": "#9467bd"}


def _series(path: str, label: str, color: str | None = None) -> JsonObject:
    s: JsonObject = {"value": path, "enabled": True, "timestampMethod": "receiveTime",
                         "label": label}
    if color:
        s["color"] = color
    return s


def _plot(title: str, ylabel: str, series: list[JsonObject]) -> JsonObject:
    return {"paths": series, "showXAxisLabels": True, "showYAxisLabels": True,
            "showLegend": True, "legendDisplay": "floating", "showPlotValuesInLegend": True,
            "isSynced": True, "xAxisVal": "timestamp", "yAxisLabel": ylabel,
            "sidebarDimension": 240, "foxglovePanelTitle": title}


def _discrete(names: dict[int, str]) -> JsonObject:
    return {"type": "discrete", "states": [
        {"value": str(v), "label": n, "color": _COLORS.get(n)} for v, n in names.items()]}


def _stack(ids: Sequence[JsonValue], direction: str = "column") -> JsonValue:
    """A mosaic tree giving each panel an equal share."""
    if len(ids) == 1:
        return ids[0]
    return {"direction": direction, "first": ids[0], "second": _stack(ids[1:], direction),
            "splitPercentage": round(100.0 / len(ids), 2)}


def build_layout(rig_id: str, muscles: Sequence[str]) -> JsonObject:
    """The layout (Foxglove's layout file format) of a rig with these muscles."""
    root = f"/pamd/{rig_id}"
    config: JsonObject = {}
    tabs = []
    for m in muscles:
        st = f"{root}/state/{m}"
        ids = [f"Plot!{m}-{panel}" for panel in PANELS]
        for pid, (panel, (title, unit, colors)) in zip(ids, PANELS.items(), strict=True):
            shown = [f for f in fields.MUSCLE if f.plot == panel]
            config[pid] = _plot(f"{m}: {title}", unit, [
                _series(f"{st}.{f.name}", f.label, colors[k % len(colors)])
                for k, f in enumerate(shown)])
        tabs.append({"title": m, "layout": _stack(ids)})
    state_id, events_id = "StateTransitions!pamd-state", "RawMessages!pamd-events"
    state_paths = [dict(_series(f"{root}/loop.state", "supervisor state"),
                        customStates=_discrete({s.value: s.name for s in State}))]
    state_paths += [dict(_series(f"{root}/state/{m}.mode", f"{m} mode"),
                         customStates=_discrete({x.value: x.name.lower() for x in Mode}))
                    for m in muscles]
    config[state_id] = {"paths": state_paths, "isSynced": True, "showPoints": True,
                        "foxglovePanelTitle": "state and modes"}
    config[events_id] = {"topicPath": f"{root}/events", "diffTopicPath": "",
                         "diffMethod": "custom", "diffEnabled": False,
                         "showFullMessageForDiff": False, "expansion": "all", "fontSize": 12,
                         "foxglovePanelTitle": "latest event"}
    if len(tabs) == 1:
        left: JsonValue = tabs[0]["layout"]
    else:
        left = "Tab!pamd-muscles"
        config[left] = {"activeTabIdx": 0, "tabs": tabs}
    return {"configById": config, "globalVariables": {}, "userNodes": {},
            "playbackConfig": {"speed": 1},
            "layout": {"direction": "row", "first": left,
                       "second": _stack([state_id, events_id]), "splitPercentage": 65}}


def layout_json(rig_id: str, muscles: Sequence[str]) -> str:
    return json.dumps(build_layout(rig_id, muscles), indent=2) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pamd.client.layout",
                                description="Write the Foxglove layout of a rig.")
    p.add_argument("--config", metavar="FILE", help="rig config (default: built-in sim)")
    p.add_argument("--out", metavar="FILE", help="where to write it (default: stdout)")
    args = p.parse_args(argv)

    cfg = load_config(args.config)
    text = layout_json(cfg.rig.rig_id, [m.name for m in cfg.rig.muscles])
    if args.out:
        write_atomic(args.out, text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
