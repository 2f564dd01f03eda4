"""The command credential's file (`pamd.net.credential`): made once, readable by the
daemon's user and group only, kept across restarts, never taken from a directory
another user controls; found by the client in the same places (or as told); compared
by hash. And rig ids are names: the client refuses a pattern before sending."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from pamd.net import credential as cr
from pamd.net.client.client import BadRigName, Client, rig_name
from pamd.net.zconf import NoDaemon


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


def test_the_check_compares_hashes() -> None:
    sha = cr.digest("a" * 43)
    assert cr.matches(cr.attachment("a" * 43), sha)
    for bad in (None, b"", b"a" * 43, cr.attachment("a" * 42), cr.attachment("b" * 43),
                cr.attachment("a" * 43 + "x")):
        assert not cr.matches(bad, sha)


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
