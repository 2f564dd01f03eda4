"""`pamd tune --loop onoff --plot FILE` (pamd/client/tune/onoff_plot.py): the figure draws
each of the ten pulses per muscle around its own window from the data the analysis
measured (the valve's open interval, the means where they were taken, the 300 ms
pulses' fastest length change), marks an unsound pulse, and is written as a PNG;
without matplotlib `--plot` is refused with the install hint before anything runs.
The step test is the session's one run (tests/tune/conftest.py)."""

from __future__ import annotations

import struct
from dataclasses import replace
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import pytest

from pamd.client.cli import tune as tune_cli
from pamd.client.tune.onoff_plot import onoff_figure, plot_onoff
from pamd.client.tune.onoff_steps import (
    PULSES,
    SPEED_PULSE_S,
    SPEED_WINDOW_S,
    WINDOW_S,
    StepTest,
    unsound,
)
from pamd.client.tune.tune_report import pyplot
from pamd.wire.errors import PamdError
from tests.tune.conftest import ONOFF


def _by_gid(ax: Any, gid: str) -> list[Any]:
    return [a for a in (*ax.lines, *ax.patches) if a.get_gid() == gid]


def test_the_trace_is_what_was_measured(onoff_run: tuple[StepTest, Path]) -> None:
    """Each pulse keeps its stretch of the recording: the means over its windows are the
    step the analysis measured, and the stretch covers both windows."""
    test, _ = onoff_run
    assert [r.pulse for r in test.responses()] == list(PULSES)
    for r in test.responses():
        tr = r.trace
        assert unsound(r) is None  # the sim's pulses are all sound
        assert tr.t_s[0] <= -2 * WINDOW_S + 1e-9 and tr.t_s[-1] >= tr.after_from_s + WINDOW_S
        before = (tr.t_s >= -WINDOW_S - 1e-9) & (tr.t_s < -1e-9)
        after = (tr.t_s >= tr.after_from_s - 1e-9) & (tr.t_s < tr.after_from_s + WINDOW_S - 1e-9)
        assert before.sum() == after.sum() == 50  # 1 kHz
        assert np.mean(tr.pressure_bar[before]) == pytest.approx(tr.pressure_before_bar)
        assert np.mean(tr.pressure_bar[after]) - tr.pressure_before_bar == pytest.approx(
            r.pressure_step_bar)
        assert np.mean(tr.length_mm[after]) - tr.length_before_mm == pytest.approx(
            r.length_step_mm)
        assert 0.0 <= tr.fastest_from_s < tr.after_from_s


def test_the_figure_draws_every_pulse_per_muscle_each_around_its_window(
        onoff_run: tuple[StepTest, Path]) -> None:
    """One column per pulse, the shortest pulses' repeats each in its own, titled with
    its repeat."""
    test, _ = onoff_run
    titles = ["inflate 40 ms", "exhaust 40 ms", "inflate 6 ms 1/3", "exhaust 6 ms 1/3",
              "inflate 6 ms 2/3", "exhaust 6 ms 2/3", "inflate 6 ms 3/3", "exhaust 6 ms 3/3",
              "inflate 300 ms", "exhaust 300 ms"]
    plt = pyplot()
    fig = onoff_figure(plt, {"m1": test, "m2": test}, 3.0)
    try:
        axes = np.array(fig.axes).reshape(4, len(PULSES))  # per muscle: pressure over length
        for row, muscle in enumerate(("m1", "m1", "m2", "m2")):
            for ax, r, title in zip(axes[row], test.responses(), titles, strict=True):
                pressure = row % 2 == 0
                if pressure:
                    assert ax.get_title() == f"{muscle}: {title}"
                [shade] = _by_gid(ax, "open")  # the valve open, in data x (ms)
                x = shade.get_patch_transform().transform(shade.get_path().vertices)[:, 0]
                assert (x.min(), x.max()) == pytest.approx((0.0, 1e3 * r.pulse_s))
                [before], [after] = _by_gid(ax, "before"), _by_gid(ax, "after")
                level = r.trace.pressure_before_bar if pressure else r.trace.length_before_mm
                step = r.pressure_step_bar if pressure else r.length_step_mm
                assert list(before.get_xdata()) == pytest.approx([-1e3 * WINDOW_S, 0.0])
                assert list(before.get_ydata()) == pytest.approx([level, level])
                a = 1e3 * r.trace.after_from_s
                assert list(after.get_xdata()) == pytest.approx([a, a + 1e3 * WINDOW_S])
                assert list(after.get_ydata()) == pytest.approx([level + step] * 2)
                trace = [ln for ln in ax.lines if ln.get_gid() is None]
                assert len(trace) == 1 and min(trace[0].get_xdata()) < -1e3 * WINDOW_S
                assert max(trace[0].get_xdata()) > a + 1e3 * WINDOW_S
                fastest = _by_gid(ax, "fastest")
                if pressure or r.pulse.pulse_s != SPEED_PULSE_S:
                    assert not fastest
                    continue
                [seg] = fastest  # its slope is the speed measured
                xs, ys = seg.get_xdata(), seg.get_ydata()
                assert xs[1] - xs[0] == pytest.approx(1e3 * SPEED_WINDOW_S)
                assert abs(ys[1] - ys[0]) / SPEED_WINDOW_S == pytest.approx(r.speed_mm_s)
        assert "3 bar" in fig.texts[0].get_text()  # the suptitle
        assert axes[0][0].get_ylabel() == "m1: pressure (bar)"
        assert axes[3][0].get_ylabel() == "m2: length (mm)"
    finally:
        plt.close(fig)


def test_an_unsound_pulse_is_marked(onoff_run: tuple[StepTest, Path]) -> None:
    """A 40 ms inflate pulse that moved nothing: its pressure panel framed red with
    the check's reason; the others not."""
    test, _ = onoff_run
    dead = replace(test.rate[0], pressure_step_bar=0.0)
    spoilt = replace(test, rate=(dead, test.rate[1]))
    plt = pyplot()
    fig = onoff_figure(plt, {"m1": spoilt}, 3.0)
    try:
        red = [ax for ax in fig.axes
               if any(s.get_edgecolor()[:3] == (1.0, 0.0, 0.0) for s in ax.spines.values())]
        assert red == [fig.axes[0]]
        said = " ".join(t.get_text() for t in fig.axes[0].texts).replace("\n", " ")
        assert "moved the pressure by +0.0000 bar" in said
    finally:
        plt.close(fig)


def test_a_repeat_left_out_says_so(onoff_run: tuple[StepTest, Path]) -> None:
    """The second exhaust repeat held open (twice the others' step): its title says
    it is left out of the typical step; the other repeats' do not."""
    test, _ = onoff_run
    shortest = list(test.shortest)
    shortest[3] = replace(shortest[3], pressure_step_bar=2.0 * shortest[3].pressure_step_bar)
    plt = pyplot()
    fig = onoff_figure(plt, {"m1": replace(test, shortest=tuple(shortest))}, 3.0)
    try:
        titles = [ax.get_title() for ax in fig.axes[2:8]]
        assert titles == ["m1: inflate 6 ms 1/3", "m1: exhaust 6 ms 1/3", "m1: inflate 6 ms 2/3",
                          "m1: exhaust 6 ms 2/3, left out", "m1: inflate 6 ms 3/3",
                          "m1: exhaust 6 ms 3/3"]
    finally:
        plt.close(fig)


def test_the_png_is_written(onoff_run: tuple[StepTest, Path], tmp_path: Path) -> None:
    test, _ = onoff_run
    png = tmp_path / "onoff.png"
    plot_onoff(str(png), {"m1": test}, 3.0)
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert width > 2500 and 400 < height < width  # ten panels wide, two high
    assert len(data) > 50_000  # drawn traces, not an empty canvas


@pytest.mark.usefixtures("without_matplotlib")
def test_plot_without_matplotlib_is_refused_before_anything_runs(
        monkeypatch: pytest.MonkeyPatch, pamd_here: Any, tmp_path: Path) -> None:
    def ran(*_a: Any, **_k: Any) -> NoReturn:
        raise AssertionError("the step test ran before --plot was checked")

    monkeypatch.setattr(tune_cli, "run_onoff", ran)
    with pytest.raises(PamdError, match=r"pip install 'pamd\[plot\]'"):
        pyplot()
    r = pamd_here("tune", "--clock", "virtual", "--loop", "onoff", "--config", str(ONOFF),
                  "--out", str(tmp_path / "run"), "--plot", str(tmp_path / "p.png"),
                  cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    assert "--plot needs matplotlib: pip install 'pamd[plot]'" in r.stderr
    assert not list(tmp_path.iterdir())  # no recording, no PNG
