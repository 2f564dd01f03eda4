"""A client process for the network tests: its own Zenoh session (pamd.client.remote),
driven by the test through stdin/stdout, one JSON object per line each way.

Start: `python agent.py [--connect EP] [--zenoh-config FILE]`; the first line out is
{"ready": true} or {"error": "..."} (then it exits). Requests ({"op": ...}):
  rigs                                   -> {"rigs": [...]}
  status   rig                           -> the status reply
  cmd      rig verb [payload|raw] [user] -> the verdict
  cmds     rig list of {verb, payload|raw}  -> list of verdicts (one session, in order)
  subscribe name key                     -> {} (a ring-channel subscriber)
  until    name field [above] [below] [kind] seconds -> the first message (or sample)
           that meets it: {"met": bool, "msg": ..., "n": messages seen}
  drain    name                          -> {"msgs": [...]} everything received so far
  stream   rig muscle bar deadman_s period_s count -> verdicts of repeated setpoints
  flood    rig verb n                    -> {"ok": n, "rate_limited": n, "other": n}
A client that gets no answer replies {"no_daemon": "..."}.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from pamd.client.remote import Client
from pamd.wire.zconf import NoDaemon


def _payload(req: dict[str, Any]) -> Any:
    return req["raw"] if "raw" in req else req.get("payload")


def _matches(v: dict[str, Any], req: dict[str, Any]) -> bool:
    x = v.get(req["field"]) if "field" in req else None
    if "kind" in req and v.get("kind") != req["kind"]:
        return False
    if "contains" in req and req["contains"] not in json.dumps(v):
        return False
    if "field" in req and not isinstance(x, (int, float)):
        return False
    if "above" in req and not x > req["above"]:
        return False
    return not ("below" in req and not x < req["below"])


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect")
    ap.add_argument("--zenoh-config")
    a = ap.parse_args()
    try:
        cl = Client(a.zenoh_config, a.connect)
    except NoDaemon as exc:
        print(json.dumps({"error": str(exc)}), flush=True)
        return 7
    subs: dict[str, Any] = {}
    print(json.dumps({"ready": True, "zid": str(cl.session.zid())}), flush=True)
    for line in sys.stdin:
        req = json.loads(line)
        op = req["op"]
        try:
            out = handle(cl, subs, op, req)
        except NoDaemon as exc:
            out = {"no_daemon": str(exc)}
        print(json.dumps(out), flush=True)
    cl.close()
    return 0


def handle(cl: Client, subs: dict[str, Any], op: str, req: dict[str, Any]) -> Any:
    if op == "rigs":
        return {"rigs": cl.rigs()}
    if op == "status":
        return cl.status(req["rig"], req.get("timeout", 3.0))
    if op == "cmd":
        return cl.command(req["rig"], req["verb"], _payload(req), user=req.get("user", "tester"),
                          timeout_s=req.get("timeout", 10.0))
    if op == "cmds":
        out = []
        for c in req["list"]:
            try:
                out.append(cl.command(req["rig"], c["verb"], _payload(c), user="tester"))
            except NoDaemon as exc:
                out.append({"no_daemon": str(exc)})
        return out
    if op == "subscribe":
        subs[req["name"]] = cl.subscribe(req["key"])
        return {}
    if op == "drain":
        msgs = []
        while (s := subs[req["name"]].try_recv()) is not None:
            msgs.append(json.loads(s.payload.to_bytes()))
        return {"msgs": msgs}
    if op == "until":
        sub, n = subs[req["name"]], 0
        deadline = time.monotonic() + req.get("seconds", 20.0)
        while time.monotonic() < deadline:
            s = sub.try_recv()
            if s is None:
                time.sleep(0.005)
                continue
            n += 1
            msg = json.loads(s.payload.to_bytes())
            samples = [{k: v[i] for k, v in msg.items() if isinstance(v, list)}
                       for i in range(len(msg.get("tick", [])))] if "tick" in msg else [msg]
            for v in samples:
                if _matches(v, req):
                    return {"met": True, "msg": v, "n": n}
        return {"met": False, "n": n}
    if op == "stream":
        out = []
        for _ in range(req["count"]):
            out.append(cl.command(req["rig"], "setpoint", {
                "muscle": req["muscle"], "bar": req["bar"], "deadman_s": req["deadman_s"]}))
            time.sleep(req["period_s"])
        return out
    if op == "flood":
        counts = {"ok": 0, "rate_limited": 0, "other": 0}
        for _ in range(req["n"]):
            v = cl.command(req["rig"], req["verb"], req.get("payload", {}), user="flood")
            key = ("ok" if v.get("ok") else
                   "rate_limited" if "rate limited" in str(v.get("error")) else "other")
            counts[key] += 1
        return counts
    if op == "big":  # `n` commands whose JSON is `bytes` long: the distinct errors
        pad = "x" * req["bytes"]
        errors: dict[str, int] = {}
        for _ in range(req["n"]):
            v = cl.command(req["rig"], req["verb"], {**req.get("payload", {}), "pad": pad},
                           user="big", timeout_s=30.0)
            e = "ok" if v.get("ok") else str(v.get("error"))[:200]
            errors[e] = errors.get(e, 0) + 1
        return errors
    if op == "burst":  # `n` commands spread over `seconds`, sent without waiting
        return _burst(cl, req)
    return {"error": f"unknown op {op!r}"}


def _burst(cl: Client, req: dict[str, Any]) -> dict[str, Any]:
    import threading

    n, lock, done = req["n"], threading.Lock(), threading.Event()
    verdicts: list[dict[str, Any]] = []

    def on_reply(reply: Any) -> None:
        try:
            v = json.loads(reply.ok.payload.to_bytes()) if reply.ok else {"error": "err"}
        except Exception as exc:
            v = {"error": repr(exc)}
        with lock:
            verdicts.append(v)
            if len(verdicts) >= n:
                done.set()

    t0 = time.perf_counter()
    for i in range(n):
        while time.perf_counter() < t0 + i * req["seconds"] / n:
            time.sleep(0.0005)
        body = json.dumps(req["payloads"][i % len(req["payloads"])]).encode()
        cl.send(req["rig"], req["verb"], body, on_reply, timeout_s=req.get("timeout", 60.0))
    done.wait(req.get("timeout", 60.0) + 5.0)
    with lock:
        errors: dict[str, int] = {}
        for v in verdicts:
            if not v.get("ok"):
                e = str(v.get("error"))[:120]
                errors[e] = errors.get(e, 0) + 1
        return {"answered": len(verdicts), "ok": sum(1 for v in verdicts if v.get("ok")),
                "errors": errors, "send_s": time.perf_counter() - t0}


if __name__ == "__main__":
    sys.exit(main())
