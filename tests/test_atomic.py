"""Every file pamd keeps is written by one writer, whole or not at all (issue 37 item 3,
`pamd.wire.atomic`): a temporary file beside it, synced and renamed; a failed write leaves
the old file and says so, naming it, with a non-zero exit. Before,
`(ulimit -f 3; pamd commission t.yaml --clock virtual --rest-s 2 --hold-s 1 --save)`
cut t.yaml to 3072 bytes, its control: and safety: sections gone, and
`pamd check-config` called it valid."""

from __future__ import annotations

import os
import re
import resource
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from pamd.client.tune.save import save_values
from pamd.config import load_config
from pamd.wire.atomic import atomic_text, write_atomic
from pamd.wire.errors import FileWriteError

REPO = Path(__file__).resolve().parents[1]
#: files written elsewhere than pamd.wire.atomic, and why: streams written as they are made
#: (recordings recover on their own), a lock, a device, a test hook
NOT_KEPT = {
    "pamd/wire/record/": "MCAP recordings are streams, recovered by `pamd recover`",
    "pamd/daemon/service/riglock.py": "a lock file, held open and locked, never replaced",
    "pamd/loop/rt.py": "/dev/cpu_dma_latency, a device",
    "pamd/iohost/process.py": "a test hook's list of modules (PAMD_TEST_IO_MODULES)",
    "pamd/emulate/testing.py": "the tests' config files in their own temporary directory",
    "pamd/wire/atomic.py": "the writer itself",
}


def _big_config(tmp_path: Path) -> Path:
    """config/sim.yaml with a lab's comments: 5 KB, more than a 3 KB size limit."""
    text = (REPO / "config" / "sim.yaml").read_text()
    text += "".join(f"# a comment a lab's config carries, line {i}, about its rig\n"
                    for i in range(60))
    path = tmp_path / "t.yaml"
    path.write_text(text)
    return path


def test_a_file_is_replaced_whole_keeping_its_mode_and_its_link(tmp_path: Path) -> None:
    path = tmp_path / "a.yaml"
    path.write_text("old\n")
    os.chmod(path, 0o640)
    link = tmp_path / "link.yaml"
    link.symlink_to(path)
    write_atomic(link, "new\n")
    assert path.read_text() == "new\n" and link.is_symlink()  # the target, not the link
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
    write_atomic(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.yaml", "b.bin", "link.yaml"]


def test_a_write_that_fails_leaves_the_old_file_and_no_temporary(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "a.yaml"
    path.write_text("old\n")
    with pytest.raises(ValueError), atomic_text(path) as fh:  # the writer's own failure
        fh.write("half")
        raise ValueError("the caller failed")
    assert path.read_text() == "old\n"

    def no_rename(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", no_rename)
    with pytest.raises(FileWriteError) as exc:
        write_atomic(path, "new\n")
    assert str(exc.value) == (f"cannot write {path}: No space left on device; {path} is as "
                              "it was (free space, permissions or a file-size limit?)")
    assert exc.value.exit_code == 9 and isinstance(exc.value, OSError)
    assert path.read_text() == "old\n" and [p.name for p in tmp_path.iterdir()] == ["a.yaml"]
    with pytest.raises(FileWriteError, match="no new.yaml was written"):
        write_atomic(tmp_path / "new.yaml", "x")
    with pytest.raises(FileExistsError):  # exclusive: never over a file that is there
        monkeypatch.undo()
        write_atomic(path, "other", exclusive=True)
    assert path.read_text() == "old\n"


def _limit_3_kib() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (3072, 3072))  # Python ignores SIGXFSZ


def test_a_save_beyond_a_file_size_limit_keeps_the_config(tmp_path: Path) -> None:
    """`pamd tune --save` and `pamd commission --save` write through `save_values`: under
    a 3 KiB file-size limit (a full disk) the 5 KB config stays whole and the error names
    it (the CLI exits 9 with it)."""
    path = _big_config(tmp_path)
    before = path.read_bytes()
    code = ("import sys\nfrom pamd.client.tune.save import save_values\n"
            "from pamd.wire.errors import PamdError\n"
            "try:\n"
            f"    save_values({str(path)!r}, {{('control', 'pid', 'kp'): 0.6}})\n"
            "except PamdError as exc:\n"
            "    print(exc, file=sys.stderr); sys.exit(exc.exit_code)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=60, preexec_fn=_limit_3_kib, cwd=tmp_path)
    assert r.returncode == 9, r.stderr
    assert f"cannot write {path}: File too large; {path} is as it was" in r.stderr
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["t.yaml"]
    # the other way: without the limit the save goes through, and loads
    assert save_values(str(path), {("control", "pid", "kp"): 0.6}) == 0
    assert "kp: 0.6" in path.read_text() and load_config(str(path))


#: a direct write of a file: open()/fdopen() for writing, os.replace/os.rename, mkstemp,
#: Path.write_text/write_bytes, a figure's savefig (a text scan: fast, and a write split
#: over lines still shows its opening "open(path, 'w'")
DIRECT_WRITE = re.compile(r"""os\.(replace|rename)\(|mkstemp\(|\.write_(text|bytes)\(|"""
                          r"""\.savefig\(|\bf?d?open\([^)]*["'][wax]b?\+?["']""")


def test_every_file_pamd_keeps_goes_through_the_one_writer() -> None:
    """A new writer of its own (the seven private copies there were) fails here."""
    stray = []
    for path in sorted((REPO / "pamd").rglob("*.py")):
        rel = path.relative_to(REPO).as_posix()
        if any(rel.startswith(p) for p in NOT_KEPT):
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if DIRECT_WRITE.search(line) and not line.lstrip().startswith("#"):
                stray.append(f"{rel}:{n}: {line.strip()}")
    assert not stray, "write these through pamd.wire.atomic:\n" + "\n".join(stray)
    assert DIRECT_WRITE.search('with open(path, "w", encoding="utf-8") as fh:')  # it sees
    assert DIRECT_WRITE.search("fig.savefig(path, dpi=120)")


@pytest.mark.slow
def test_the_issues_commission_save_under_ulimit_keeps_the_config(tmp_path: Path) -> None:
    """The issue's case end to end (16 s of wall time): `pamd commission --save` under a
    3 KiB file-size limit exits 9 naming the config, which stays whole and valid."""
    path = _big_config(tmp_path)
    before = path.read_bytes()
    r = subprocess.run(  # its report to /dev/null: a terminal has no size limit
        [sys.executable, "-m", "pamd", "commission", str(path), "--clock", "virtual",
         "--rest-s", "2", "--hold-s", "1", "--save"], stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, text=True, timeout=600, preexec_fn=_limit_3_kib, cwd=tmp_path)
    assert r.returncode == 9, r.stderr[-2000:]
    assert f"cannot write {path}: File too large" in r.stderr and "Traceback" not in r.stderr
    assert path.read_bytes() == before
