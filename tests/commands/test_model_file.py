"""A `model` command's file is read, parsed, checked and timed in a child process
(`pamd.loop.commands.offload`), never in the daemon's own; the child is held to a time
limit; a model the tick cannot evaluate within its budget is refused."""

from __future__ import annotations

import json
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest

from pamd.config import LoadedConfig, load_config
from pamd.loop.commands import parse_command, prepare_command
from pamd.loop.commands.model_file import (
    MODEL_TICK_FRACTION,
    ModelSource,
    check_models_isolated,
    read_model,
)
from pamd.loop.commands.named_files import MODEL_MAX_BYTES
from pamd.loop.commands.offload import run_isolated, warm_up
from pamd.loop.commands.prepared import PreparedModelArgs
from pamd.models import registry
from pamd.models.anfis.model import AnfisModel
from pamd.models.anfis.serialize import to_dict
from pamd.models.contract import Variable
from pamd.wire.errors import CommandRefused, ConfigError

REPO = Path(__file__).resolve().parents[2]


def anfis(n_mfs: tuple[int, int]) -> AnfisModel:
    """Force and length in, within the sim muscle's travel; 3 bar out."""
    ins = [Variable("force_n", "N", 0.0, 600.0), Variable("length_mm", "mm", 140.0, 205.0)]
    rules = int(np.prod(n_mfs))
    cons = np.zeros((rules, 3))
    cons[:, 2] = 3.0
    return AnfisModel(ins, Variable("pressure_bar", "bar", 0.0, 6.0), mf_type="gaussian",
                      scaling="minmax", scale_offset=[0.0, 140.0], scale_span=[600.0, 65.0],
                      centres=[np.linspace(0.0, 1.0, n) for n in n_mfs],
                      widths=[np.full(n, 0.5 / n) for n in n_mfs], consequents=cons)


def write(path: Path, model: AnfisModel) -> Path:
    path.write_text(json.dumps(to_dict(model), separators=(",", ":")))
    return path


@pytest.fixture(scope="module")
def cfg() -> LoadedConfig:
    warm_up()  # as the daemon does when it starts: a file's time limit includes it
    return load_config(str(REPO / "config" / "sim.yaml"))


def test_the_model_is_parsed_in_another_process(tmp_path: Path, cfg: LoadedConfig,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Parsing in this process would call the patched reader and fail; the child,
    forked from the forkserver, has its own."""

    def no_parse_here(*_a: object, **_k: object) -> None:
        raise AssertionError("a model file was parsed in the daemon's process")

    monkeypatch.setattr(registry, "parse_json", no_parse_here)
    monkeypatch.setattr(registry, "model_from_dict", no_parse_here)
    path = write(tmp_path / "small.json", anfis((5, 5)))
    cmd = prepare_command(parse_command("model", {"muscle": "m1", "file": str(path)}), cfg)
    assert isinstance(cmd.args, PreparedModelArgs)
    assert cmd.args.feedforward.pressure(300.0, 180.0, 0.1, 0.0) == pytest.approx(3.0)


def test_a_model_of_too_many_rules_is_refused_before_it_reaches_the_loop(
        tmp_path: Path, cfg: LoadedConfig) -> None:
    path = write(tmp_path / "big.json", anfis((40, 40)))  # 1600 rules
    with pytest.raises(CommandRefused, match="1600 rules is too many for the tick"):
        prepare_command(parse_command("model", {"muscle": "m1", "file": str(path)}), cfg)


def test_a_model_slower_than_its_share_of_the_period_is_refused(tmp_path: Path,
                                                                cfg: LoadedConfig) -> None:
    """Timed at load: a 25-rule model takes tens of us, far more than a quarter of a
    (hypothetical) 10 us period, and far less than a quarter of 1 ms."""
    path = write(tmp_path / "m.json", anfis((5, 5)))
    src = ModelSource(str(path), "m.json")
    m, lim = cfg.muscle("m1"), cfg.limits["m1"]
    with pytest.raises(CommandRefused, match=r"one evaluation takes \d+ us, more than 25% of "
                       r"the loop's 0.01 ms period \(timed at load\)"):
        read_model(src, m, lim, 10e-6)
    assert read_model(src, m, lim, 1.0).model.n_rules == 25  # the same file, a slow loop
    assert MODEL_TICK_FRACTION == 0.25


def test_a_child_past_its_time_limit_is_killed_and_the_command_refused() -> None:
    t0 = time.monotonic()
    with pytest.raises(CommandRefused, match="model refused: 'slow.json': not read within "
                       "0.5 s"):
        run_isolated(time.sleep, 30.0, time_limit_s=0.5, what="model refused: 'slow.json'")
    assert time.monotonic() - t0 < 10.0


def test_a_child_that_dies_is_a_refusal_not_a_daemon_error() -> None:
    with pytest.raises(CommandRefused, match=r"ended \(exit code 3\) without an answer"):
        run_isolated(os._exit, 3, time_limit_s=30.0, what="plan 'x.yaml'")


def test_models_are_capped_alike_by_every_reader() -> None:
    """The docs (how-to/remote.md): a model at most 8 MiB; the remote limit and every
    reader's are one."""
    assert MODEL_MAX_BYTES == registry.MAX_FILE_BYTES == 8 * 1024 * 1024
    readme = (REPO / "docs" / "how-to" / "remote.md").read_text()
    assert "a model 8 MiB" in readme and "models are capped at 16 MiB" not in readme
    assert not re.search(r"models?[^.]{0,80}16 MiB", readme)


def test_a_reload_checks_its_model_files_in_a_child_with_line_and_key(tmp_path: Path) -> None:
    write(tmp_path / "big.json", anfis((40, 40)))
    text = (REPO / "config" / "sim.yaml").read_text()
    marker = "    load_kg: 30                # what the operator"
    assert marker in text
    cfg_path = tmp_path / "rig.yaml"
    cfg_path.write_text(text.replace(marker, "    model_file: big.json\n" + marker))
    cfg = load_config(str(cfg_path))
    with pytest.raises(ConfigError) as exc:
        check_models_isolated(cfg)
    (issue,) = exc.value.issues
    assert issue.path == "muscles[0].model_file" and issue.line is not None
    assert "1600 rules is too many for the tick" in issue.found
