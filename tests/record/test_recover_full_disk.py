"""`pamd recover` on a full disk (issue 12): it used to leave a 0-byte file. A write
that fails for real (RLIMIT_FSIZE in the recovering process: EFBIG, as a full disk
gives ENOSPC, without root) leaves nothing; a disk that lacks the room is refused
before anything is written; `--out DIR` writes where told."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.wire.errors import RecordingError
from pamd.wire.record import files

from .conftest import make_sim_config


@pytest.fixture(scope="module")
def recorded_bytes(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """A 2 s recording of the simulated rig (virtual clock), made once for the module:
    every test cuts its own copy."""
    tmp = tmp_path_factory.mktemp("recorded")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PAMD_LOCK_DIR", str(tmp / "locks"))  # as tests/conftest.py's rig_lock_dir
        d = Daemon(make_sim_config(tmp), recording=RecordingRequest(dir=str(tmp / "rec")))
        d.start(2.0)
        try:
            d.wait(timeout_s=120)
        finally:
            d.stop("test finished")
            d.wait(timeout_s=60)
            d.close()
    return Path(d.result()["recording"]["files"][0]).read_bytes()


@pytest.fixture
def cut_file(recorded_bytes: bytes, tmp_path: Path) -> Path:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recorded_bytes[: len(recorded_bytes) * 2 // 3])
    assert cut.stat().st_size > 20_000
    return cut


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (8192, 8192))  # Python ignores SIGXFSZ


def test_recover_whose_writes_fail_leaves_no_file_and_says_what_to_do(
        cut_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "fixed.mcap"
    r = subprocess.run([sys.executable, "-m", "pamd", "recover", str(cut_file), "--out",
                        str(out)], capture_output=True, text=True, timeout=120,
                       preexec_fn=_limit_file_size)
    assert r.returncode == 6, r.stdout + r.stderr
    assert "write failed (File too large); nothing was written" in r.stderr, r.stderr
    assert "--out DIR" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()  # was: a 0-byte file
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".pamd-chunk-index")]


def test_recover_refuses_before_writing_when_the_disk_lacks_the_room(
        cut_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = os.statvfs

    class Full:  # a full file system needs root to make; its statvfs answer does not
        f_bavail, f_frsize = 10, 4096

    monkeypatch.setattr(files.os, "statvfs", lambda p: Full() if p == str(tmp_path) else real(p))
    out = tmp_path / "fixed.mcap"
    with pytest.raises(RecordingError, match="its disk has 40960 bytes free") as exc:
        files.recover(str(cut_file), str(out))
    assert "--out DIR" in str(exc.value)
    assert not out.exists()


def test_recover_writes_into_the_directory_it_is_told(cut_file: Path, tmp_path: Path) -> None:
    other = tmp_path / "other-disk"
    other.mkdir()
    r = files.recover(str(cut_file), str(other))
    assert r["out"] == str(other / "cut.recovered.mcap")
    assert files.inspect(r["out"])["finalised"]
