"""The loop's worst wake-up while a maximal model file is read (issue 24, B5): a real
daemon (`pamd run`, real clock, simulated rig, telemetry on its own loopback port,
`telemetry.models_dir`) takes remote `model` commands from this separate client
process, one every `--every-s`, for `--seconds`:

- *baseline*: the commands name a small valid model (a 25-rule ANFIS, 2 kB);
- *maximal*: they name a 7.4 MB model of 180,000 rules (the attack: it must be read,
  parsed, checked and refused, since no tick can evaluate it).

Each run is recorded; its worst wake-up is that of the ticks from its first `model`
command to 3 s after its last (every tick's wake_latency_s, read back); runs
alternate (baseline, maximal, baseline, ...) so that the machine's load drifts
into both alike. Prints per pair the two worst wake-ups, their ratio, and the verdicts;
then the median ratio. The issue's goal: the ratio within 2.

    python bench/files_model_load.py [--repeat 3] [--seconds 12] [--every-s 2]
    python bench/files_model_load.py --pythonpath /work/main   # a before figure
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from net_common import free_port, wait_listening, wait_status, write_config  # noqa: E402

from pamd.client.recording import open_recording  # noqa: E402
from pamd.client.remote import Client  # noqa: E402
from pamd.models.anfis.model import AnfisModel  # noqa: E402
from pamd.models.anfis.serialize import to_dict  # noqa: E402
from pamd.models.contract import Variable  # noqa: E402
from pamd.models.registry import save_model  # noqa: E402


def anfis(n_mfs: tuple[int, int]) -> AnfisModel:
    """An ANFIS of force and length with this MF grid, within the sim muscle's travel
    (its output a plausible pressure, 3 bar)."""
    ins = [Variable("force_n", "N", 0.0, 600.0), Variable("length_mm", "mm", 140.0, 205.0)]
    lo = np.array([v.min for v in ins])
    span = np.array([v.max - v.min for v in ins])
    rules = int(np.prod(n_mfs))
    cons = np.zeros((rules, 3))
    cons[:, 2] = 3.0
    return AnfisModel(ins, Variable("pressure_bar", "bar", 0.0, 6.0), mf_type="gaussian",
                      scaling="minmax", scale_offset=lo, scale_span=span,
                      centres=[np.linspace(0.0, 1.0, n) for n in n_mfs],
                      widths=[np.full(n, 0.5 / n) for n in n_mfs], consequents=cons)


def run(cfg: str, model: str, seconds: float, every_s: float, port: int,
        env: dict[str, str], log: Any) -> tuple[dict, list[str]]:
    rec = str(Path(cfg).parent / "rec")
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg, "--json",
                             "--record", rec, "--duration", str(seconds + 8)],
                            stdout=subprocess.PIPE, stderr=log, text=True, env=env,
                            cwd=Path(cfg).parent)  # not this checkout's pamd by accident
    verdicts: list[str] = []
    try:
        wait_listening(port)
        with Client(connect=f"tcp/127.0.0.1:{port}") as c:
            wait_status(c)
            time.sleep(2.0)  # past start-up
            t_end = time.monotonic() + seconds
            while time.monotonic() < t_end:
                t0 = time.monotonic()
                v = c.command("sim", "model", {"muscle": "m1", "file": model}, timeout_s=30.0)
                verdicts.append("ok" if v.get("ok") else str(v.get("error", "?"))[:70])
                time.sleep(max(0.0, every_s - (time.monotonic() - t0)))
        out, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    res = json.loads(out)
    res["window"] = window(rec)
    return res, verdicts


def window(rec: str) -> dict[str, float]:
    """The worst and p99 wake-up of the ticks from the first `model` command to 3 s
    after the last one (read back from the run's recording: every tick's
    wake_latency_s), so start-up and shutdown stay out of it."""
    r = open_recording(rec)
    times = [e.t_s for e in r.events if e.kind == "command"
             and e.data.get("verb") == "model"]
    t, w = r.loop["t_s"], r.loop["wake_latency_s"]
    sel = w[(t >= min(times) - 0.5) & (t <= max(times) + 3.0)]
    return {"max_ms": float(sel.max()) * 1e3, "p99_ms": float(np.percentile(sel, 99)) * 1e3,
            "ticks": int(sel.size)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--every-s", type=float, default=2.0)
    ap.add_argument("--rate-hz", type=float, default=1000.0)
    ap.add_argument("--pythonpath", help="run the daemon from this checkout")
    args = ap.parse_args()
    env = dict(os.environ)
    if args.pythonpath:
        env["PYTHONPATH"] = args.pythonpath
    tmp = tempfile.mkdtemp(prefix="pamd-bench-files-")
    models = Path(tmp) / "models"
    models.mkdir()
    save_model(anfis((5, 5)), models / "small.json")
    # compact JSON, as a hostile file would be: the most rules under the 8 MiB cap
    (models / "maximal.json").write_text(json.dumps(to_dict(anfis((400, 450))),
                                                    separators=(",", ":")))
    size = (models / "maximal.json").stat().st_size
    print(f"maximal model: {size / 1e6:.1f} MB, 180000 rules; small: "
          f"{(models / 'small.json').stat().st_size / 1e3:.0f} kB, 25 rules")
    ratios = []
    for i in range(args.repeat):
        worst = {}
        for which in ("small", "maximal"):
            port = free_port()
            here = Path(tmp) / f"run-{i}-{which}"  # its own state (a latched fault stays)
            here.mkdir()
            cfg = write_config(str(here), port, realtime=False, loop_rate_hz=args.rate_hz,
                               models_dir=str(models), command_timeout_s=30.0)
            with open(here / "daemon.log", "w") as log:
                res, verdicts = run(cfg, f"{which}.json", args.seconds, args.every_s, port,
                                    env, log)
            win = res["window"]
            worst[which] = win["max_ms"]
            kinds = sorted(set(verdicts))
            print(f"pair {i + 1} {which:>7}: worst wake-up {win['max_ms']:7.2f} ms, p99 "
                  f"{win['p99_ms']:.3f} ms over {win['ticks']} ticks of the commands' "
                  f"window (whole run: worst {res['wake_latency_us']['max'] / 1e3:.1f} ms, "
                  f"overruns {res['overruns']} of {res['ticks']}); {len(verdicts)} "
                  f"commands: {'; '.join(kinds)}")
        ratios.append(worst["maximal"] / max(worst["small"], 1e-3))
        print(f"pair {i + 1}: ratio maximal/baseline worst wake-up {ratios[-1]:.2f}")
    print(f"median ratio {statistics.median(ratios):.2f} over {len(ratios)} pair(s) "
          f"(goal: <= 2)")


if __name__ == "__main__":
    main()
