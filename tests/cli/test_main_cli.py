"""The CLI entry point: a reader that goes away (`pamd status | head`) ends the verb
quietly, and library chatter stays out of the operator's terminal."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from pamd.cli.main import EXIT_BROKEN_PIPE

REPO = Path(__file__).resolve().parents[2]


def test_a_closed_pipe_ends_the_verb_without_a_traceback() -> None:
    # `pamd check-config ... | head -0`: the reader is gone before pamd writes
    proc = subprocess.Popen(
        [sys.executable, "-m", "pamd", "check-config", str(REPO / "config" / "sim.yaml")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == EXIT_BROKEN_PIPE, err
    assert "BrokenPipeError" not in err and "Traceback" not in err and "Exception" not in err



def test_emulate_is_quiet_and_stops_without_a_traceback(tmp_path: Path, socat: str) -> None:
    import signal

    import yaml

    from pamd.emulate.testing import emulated_dict, free_port, write_config

    cfg = write_config(tmp_path, emulated_dict(tmp_path, free_port(), links="pty"))
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "emulate", "--config", str(cfg)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=REPO, start_new_session=True)
    assert proc.stdout is not None
    try:
        ready = yaml.safe_load(proc.stdout.readline())
        assert ready["ready"] is True
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C at a terminal: the whole group
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0 and '"stopped": true' in out
    assert "Traceback" not in err and "Exception" not in err, err
    # pymodbus's "Server listening", canopen's NMT chatter: below warning, not shown
    assert "listening" not in err and "NMT" not in err, err
