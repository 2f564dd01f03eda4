"""What a collection directory holds (`pamd inspect DIR`): the plan, each step's load,
status, files and duration from the manifest and the files themselves (a manifest
left stale by a crash is shown as the step files' own metadata says: `Manifest.reconcile`),
the runs that worked on it, and any file the manifest does not name. A directory without a manifest
is listed file by file."""

from __future__ import annotations

import json
import os

from pamd.loop.experiment.manifest import Manifest
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import RecordingError
from pamd.wire.record import files as io_files


def _file(path: str) -> JsonObject:
    """One file's summary; a file that cannot be read is described, not raised."""
    name = os.path.basename(path)
    if not os.path.exists(path):
        return {"file": name, "status": "missing", "finalised": False, "duration_s": 0.0,
                "ticks": 0, "size_bytes": 0, "faults": []}
    try:
        info = io_files.inspect(path)
    except RecordingError as exc:
        return {"file": name, "status": f"unreadable: {exc}", "finalised": False,
                "duration_s": 0.0, "ticks": 0, "size_bytes": os.path.getsize(path),
                "faults": []}
    ticks = max((c["messages"] for c in info["channels"] if c["topic"].endswith("/loop")),
                default=0)
    return {"file": name, "status": "finalised" if info["finalised"] else "unfinished",
            "finalised": info["finalised"], "duration_s": info["duration_s"], "ticks": ticks,
            "size_bytes": info["size_bytes"], "faults": info["faults"]}


def inspect_collection(directory: str) -> JsonObject:
    if not os.path.isdir(directory):
        raise RecordingError(f"{directory}: not a directory")
    on_disk = sorted(n for n in os.listdir(directory) if n.endswith(".mcap"))
    manifest_path = os.path.join(directory, "manifest.json")
    if not os.path.exists(manifest_path):
        if not on_disk:
            raise RecordingError(f"{directory}: no manifest.json and no .mcap files: not a "
                                 "collection or a recording directory")
        fs = [_file(os.path.join(directory, n)) for n in on_disk]
        return {"directory": directory, "manifest": None, "plan": None, "steps": [],
                "other_files": fs, "runs": [], "stale": [], "summary": _summary(fs, [])}
    try:
        with open(manifest_path, encoding="utf-8") as fh:
            man = json.load(fh)
        steps_in = man["steps"]
        # a manifest left stale by a crash: shown as the step files say (not written:
        # inspecting changes nothing; a resume writes it)
        stale = Manifest(directory, man).reconcile()
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RecordingError(f"{manifest_path}: not a pamd collection manifest ({exc})"
                             ) from None
    named: set[str] = set()
    steps = []
    for s in steps_in:
        fs = [_file(os.path.join(directory, f)) for f in s.get("files", [])]
        named.update(s.get("files", []))
        steps.append({"index": s.get("index"), "name": s.get("name"),
                      "load_kg": s.get("load_kg"), "status": s.get("status"), "files": fs,
                      "duration_s": sum(f["duration_s"] for f in fs),
                      "ticks": sum(f["ticks"] for f in fs)})
    others = [_file(os.path.join(directory, n)) for n in on_disk if n not in named]
    plan = man.get("plan", {})
    rig = man.get("rig", {})
    return {"directory": directory, "manifest": manifest_path, "plan": plan.get("name"),
            "plan_file": plan.get("file"), "rig_id": rig.get("rig_id"),
            "created": man.get("created"), "steps": steps, "other_files": others,
            "runs": man.get("runs", []), "stale": stale,
            "summary": _summary([f for s in steps for f in s["files"]] + others, steps)}


def _summary(fs: list[JsonObject], steps: list[JsonObject]) -> JsonObject:
    done = sum(1 for s in steps if s.get("status") == "done")
    return {"files": len(fs), "duration_s": sum(f["duration_s"] for f in fs),
            "size_bytes": sum(f["size_bytes"] for f in fs),
            "unfinished_files": [f["file"] for f in fs if not f["finalised"]],
            "steps": len(steps), "steps_done": done,
            "faults": [x for f in fs for x in f["faults"]]}


def print_collection(info: JsonObject) -> None:
    s = info["summary"]
    if info["manifest"] is None:
        print(f"{info['directory']}: {s['files']} recording(s), no manifest (not a "
              "collection)")
    else:
        print(f"{info['directory']}: collection of plan {info['plan']} (rig "
              f"{info['rig_id']}), created {info['created']}; {s['steps_done']} of "
              f"{s['steps']} steps done")
        if info.get("stale"):
            print(f"  the manifest was stale (a crash?); shown as the step files say: "
                  f"{'; '.join(info['stale'])} (`pamd collect --resume` writes it)")
        print(f"  {'step':<5} {'name':<18} {'load':>7}  {'status':<12} {'duration':>9}  files")
        for st in info["steps"]:
            load = "-" if st["load_kg"] is None else f"{st['load_kg']:g} kg"
            names = ", ".join(f"{f['file']} ({f['status']}, {f['ticks']} ticks)"
                              for f in st["files"]) or "none yet"
            print(f"  {st['index'] + 1:<5} {st['name']:<18} {load:>7}  {st['status']:<12} "
                  f"{st['duration_s']:>7.1f} s  {names}")
    for f in info["other_files"]:
        what = "" if info["manifest"] is None else " (not a step's: before the plan or after)"
        print(f"  file {f['file']}: {f['status']}, {f['ticks']} ticks, {f['duration_s']:.1f} s"
              f"{what}")
    for r in info["runs"]:
        faults = "; ".join(r.get("faults") or []) or "none"
        print(f"  run finished {r.get('finished')}: {r.get('outcome')} from step "
              f"{int(r.get('start_step') or 0) + 1}, {r.get('ticks')} ticks, lost records "
              f"{r.get('lost_records')}, faults: {faults}")
    print(f"  total: {s['files']} file(s), {s['duration_s']:.1f} s, "
          f"{s['size_bytes'] / 1e6:.1f} MB")
    if s["unfinished_files"]:
        print(f"  unfinished: {', '.join(s['unfinished_files'])} (run `pamd recover` on "
              "each)")
