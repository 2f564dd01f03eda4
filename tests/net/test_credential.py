"""The command credential's file (`pamd.wire.credential`): made once, readable by the
daemon's user and group only, kept across restarts, never taken from a directory
another user controls; found by the client in the same places (or as told); each
command signed with it, never replayable; rotated in place. And rig ids are names: the
client refuses a pattern before sending."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from pamd.client.remote import BadRigName, Client, rig_name
from pamd.wire import credential as cr
from pamd.wire.zconf import NoDaemon


@pytest.fixture
def token_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "tokens"
    monkeypatch.setenv(cr.TOKEN_DIR_ENV, str(d))
    for env in (cr.TOKEN_FILE_ENV, cr.TOKEN_ENV, "RUNTIME_DIRECTORY"):
        monkeypatch.delenv(env, raising=False)
    monkeypatch.setattr(cr, "token_dirs", lambda: [str(d)])  # not this machine's own
    monkeypatch.setattr(cr, "SERVICE_DIR", str(tmp_path / "service"))
    return d


def test_the_daemon_makes_a_token_readable_by_its_user_and_group_only(token_dir: Path) -> None:
    path, sha = cr.ensure_token("sim")
    assert path == str(token_dir / "pamd-sim.token")
    st = os.stat(path)
    assert stat.S_IMODE(st.st_mode) == 0o640 and st.st_uid == os.getuid()
    assert stat.S_IMODE(os.stat(token_dir).st_mode) == 0o700
    token = Path(path).read_text().strip()
    assert cr.TOKEN_RE.match(token) and cr.digest(token) == sha
    assert token not in sha  # only the hash travels to the io process
    assert cr.ensure_token("sim") == (path, sha)  # kept: a restart keeps its clients' token
    assert cr.ensure_token("other")[1] != sha  # one per rig


def test_a_file_that_is_not_a_token_of_ours_is_replaced(token_dir: Path) -> None:
    token_dir.mkdir(mode=0o700)
    f = token_dir / "pamd-sim.token"
    f.write_text("short\n")
    path, sha = cr.ensure_token("sim")
    assert cr.digest(Path(path).read_text().strip()) == sha
    os.chmod(path, 0o644)  # readable by anyone: not kept
    path2, sha2 = cr.ensure_token("sim")
    assert sha2 != sha and stat.S_IMODE(os.stat(path2).st_mode) == 0o640


def test_a_world_writable_directory_is_not_used(token_dir: Path) -> None:
    token_dir.mkdir()
    os.chmod(token_dir, 0o777)  # anyone could plant or swap the file
    with pytest.raises(cr.CredentialError, match="not a directory of this user's"):
        cr.ensure_token("sim")


def test_the_client_finds_the_token_where_the_daemon_wrote_it_or_where_told(
        token_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert cr.find_token("sim")[0] is None
    path, sha = cr.ensure_token("sim")
    tok, where = cr.find_token("sim")
    assert tok is not None and cr.digest(tok) == sha and where == path
    other = tmp_path / "copy.token"
    other.write_text("u" * 43 + "\n")
    assert cr.find_token("sim", str(other))[0] == "u" * 43  # --token-file first
    monkeypatch.setenv(cr.TOKEN_ENV, "v" * 43)
    assert cr.find_token("sim")[0] == "v" * 43  # then PAMD_TOKEN
    monkeypatch.setenv(cr.TOKEN_FILE_ENV, str(other))
    assert cr.find_token("sim")[0] == "u" * 43  # PAMD_TOKEN_FILE before it
    monkeypatch.setenv(cr.TOKEN_FILE_ENV, "/etc/passwd")  # never sends what is not a token
    assert cr.find_token("sim")[0] is None


def test_a_signature_is_checked_against_the_tokens_hash_in_constant_time() -> None:
    sha = cr.digest("a" * 43)
    v = cr.Verifier(sha, "n0")
    body = b'{"muscle": "m1"}'
    assert v.check(cr.Signer("a" * 43).attachment("sim", "hold", body, "n0"), "sim", "hold",
                   body) is None
    for bad in (b"a" * 43, cr.Signer("a" * 42).attachment("sim", "hold", body, "n0"),
                cr.Signer("a" * 43).attachment("other", "hold", body, "n0"),
                cr.Signer("a" * 43).attachment("sim", "stop", body, "n0"),
                b"pamd-mac1 zz 1 n0 00", b"pamd-mac1 abcdef12 x n0 00"):
        assert v.check(bad, "sim", "hold", body) == cr.BAD, bad
    assert v.check(None, "sim", "hold", body) == cr.NONE
    assert v.check(b"pamd-token:" + b"a" * 43, "sim", "hold", body) == cr.CLEAR
    assert "a" * 43 not in cr.Signer("a" * 43).attachment("sim", "hold", body, "n0").decode()


def test_counters_go_up_and_a_forgotten_client_cannot_be_replayed(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cr, "MAX_CLIENTS", 2)
    v = cr.Verifier(cr.digest("a" * 43), "n0")
    s1, s2, s3 = (cr.Signer("a" * 43) for _ in range(3))
    first = s1.attachment("sim", "hold", b"{}", "n0")
    assert v.check(first, "sim", "hold", b"{}") is None
    assert v.check(first, "sim", "hold", b"{}") == cr.REPLAY
    for s in (s2, s3):  # s1 is forgotten: its counters are below the floor
        assert v.check(s.attachment("sim", "hold", b"{}", "n0"), "sim", "hold", b"{}") is None
    assert "abcd" not in v.last and len(v.last) == 2
    assert v.check(first, "sim", "hold", b"{}") == cr.REPLAY
    assert v.check(s1.attachment("sim", "hold", b"{}", "n0"), "sim", "hold", b"{}") is None


def test_rotating_the_token_needs_no_deletion_and_the_io_process_takes_it(
        token_dir: Path) -> None:
    path, sha = cr.ensure_token("sim")
    watch = cr.TokenWatch(path, period_s=0.0)
    assert watch.changed(1.0) is None  # nothing new
    old = cr.find_token("sim")[0]
    assert cr.rotate_token("sim") == path
    new = cr.find_token("sim")[0]
    assert new is not None and new != old
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o640
    assert watch.changed(2.0) == cr.digest(new)  # the io process's key from now on
    assert watch.changed(3.0) is None
    assert list(token_dir.iterdir()) == [Path(path)]  # no temporary file left behind
    with pytest.raises(cr.CredentialError, match="no command token"):
        cr.rotate_token("other")


@pytest.mark.parametrize("rig", ["*", "**", "s*", "$*", "a/b", "pamd/**", "", "x?", "#"])
def test_a_rig_id_that_is_a_pattern_is_refused_by_the_client(rig: str) -> None:
    with pytest.raises(BadRigName, match="not a rig's name"):
        rig_name(rig)


def test_a_rig_name_passes() -> None:
    assert rig_name("sim") == "sim" and rig_name("lab-2.rig_a") == "lab-2.rig_a"


def test_a_client_with_no_rig_named_refuses_when_several_answer_and_lists_them() -> None:
    c = Client.__new__(Client)  # no session: the rigs alive are given
    c.where = "tcp/127.0.0.1:7447"
    c.rigs = lambda timeout_s=1.5: ["bench-a", "sim"]  # type: ignore[method-assign]
    with pytest.raises(NoDaemon, match="several rigs answer via tcp/127.0.0.1:7447: "
                       "bench-a, sim; name one with --rig"):
        c.rig(None)
    assert c.rig("sim") == "sim"  # named: no question asked
    c.rigs = lambda timeout_s=1.5: ["sim"]  # type: ignore[method-assign]
    assert c.rig(None) == "sim"
