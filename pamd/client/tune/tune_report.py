"""What `pamd tune` shows: the fit of each step, the model and the new gains beside
the present ones, the predicted and measured step responses, and (`--plot`) a PNG."""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np

from pamd.client.tune.ident_run import LoopPlan
from pamd.client.tune.step_responses import StepResponse, position_gains, pressure_gains
from pamd.client.tune.yamledit import KeyPath, change_row
from pamd.config import LoadedConfig
from pamd.config.gains import position_plant, pressure_plant
from pamd.loop.control.tuning import Fopdt
from pamd.wire.atomic import save_figure
from pamd.wire.errors import PamdError

#: The plant keys of each loop, in the order of the FOPDT model's gain, lag, dead time.
PLANT_KEYS: dict[str, tuple[KeyPath, KeyPath, KeyPath]] = {
    "pressure": (("control", "plant", "gain_bar_per_bar"), ("control", "plant", "lag_s"),
                 ("control", "plant", "dead_time_s")),
    "position": (("control", "position", "plant", "gain_mm_per_bar"),
                 ("control", "position", "plant", "lag_s"),
                 ("control", "position", "plant", "dead_time_s")),
}


@dataclass(frozen=True)
class Present:
    """A loop's gains by their config keys (present or new), and the plant they were
    derived from (`control.plant`, `control.position.plant`: what the config judges
    gains against, `pamd.config.gains`)."""

    loop: str
    gains: dict[KeyPath, float]

    @staticmethod
    def from_model(loop: str, model: Fopdt) -> Present:
        plant = dict(zip(PLANT_KEYS[loop], (model.gain, model.tau_s, model.dead_time_s),
                         strict=True))
        if loop == "pressure":
            g = pressure_gains(model)
            return Present(loop, {("control", "pid", "kp"): g.kp,
                                  ("control", "pid", "ki_per_s"): g.ki_per_s,
                                  ("control", "rate_feedforward_s"): g.rate_feedforward_s,
                                  **plant})
        x = position_gains(model)
        return Present(loop, {("control", "position", "pid", "kp_bar_per_mm"): x.kp_bar_per_mm,
                              ("control", "position", "pid", "ki_bar_per_mm_s"):
                              x.ki_bar_per_mm_s, **plant})

    def key_values(self) -> dict[KeyPath, float]:
        return dict(self.gains)


def present_gains(cfg: LoadedConfig, loop: str, muscle: str | None = None) -> Present:
    """The gains in force: the rig's, or those muscle `muscle` runs on (its own), and
    the plant they are judged against (stated, or the default)."""
    c = cfg.rig.control if muscle is None else cfg.control_of(muscle)
    if loop == "pressure":
        pp = pressure_plant(c)
        return Present(loop, {("control", "pid", "kp"): c.pid.kp,
                              ("control", "pid", "ki_per_s"): c.pid.ki_per_s,
                              ("control", "rate_feedforward_s"): c.rate_feedforward_s,
                              **dict(zip(PLANT_KEYS[loop], (pp.gain, pp.lag_s, pp.dead_time_s),
                                         strict=True))})
    p = c.position.pid
    xp = position_plant(c)
    return Present(loop, {("control", "position", "pid", "kp_bar_per_mm"): p.kp_bar_per_mm,
                          ("control", "position", "pid", "ki_bar_per_mm_s"): p.ki_bar_per_mm_s,
                          **dict(zip(PLANT_KEYS[loop], (-xp.gain, xp.lag_s, xp.dead_time_s),
                                     strict=True))})


def print_fits(title: str, unit: str, fits: list[tuple[StepResponse, Fopdt]], model: Fopdt) -> None:
    print(title)
    print(f"  {'step':14s} {'gain ' + unit:>14s} {'dead time ms':>13s} {'tau ms':>8s} "
          f"{'t63 ms':>8s} {'rms fit':>8s}")
    for s, f in fits:
        print(f"  {s.label:14s} {f.gain:14.3f} {1e3 * f.dead_time_s:13.1f} "
              f"{1e3 * f.tau_s:8.1f} {1e3 * f.t63_s:8.1f} {f.rms_error:8.4f}")
    print(f"  {'model (mean)':14s} {model.gain:14.3f} {1e3 * model.dead_time_s:13.1f} "
          f"{1e3 * model.tau_s:8.1f} {1e3 * model.t63_s:8.1f}")


def predicted_vs_measured(model: Fopdt, step: StepResponse, t_after_s: np.ndarray) -> list[
        tuple[float, float, float]]:
    """(t after the step, measured change, the model's change) at the times given."""
    t = step.t_s - step.t_step_s
    y0 = float(step.y[t < 0].mean())
    out = []
    for ta in t_after_s:
        k = int(np.searchsorted(t, ta))
        if k >= len(t):
            break
        out.append((float(t[k]), float(step.y[k] - y0),
                    float(model.step_response([t[k]], step.amplitude)[0])))
    return out


def model_rms_error(model: Fopdt, step: StepResponse) -> float:
    """The rms difference between the design model's response and the step's."""
    t = step.t_s - step.t_step_s
    after = t >= 0
    y0 = float(step.y[~after].mean())
    d = (step.y[after] - y0) - model.step_response(t[after], step.amplitude)
    return float(np.sqrt(np.mean(d * d)))


def print_comparison(lp: LoopPlan, model: Fopdt, present: Present, new: Present,
                     fits: list[tuple[StepResponse, Fopdt]]) -> None:
    out_unit = "bar" if lp.output_column == "pressure_bar" else "mm"
    print(f"Model: gain {model.gain:.3f} {lp.unit}, dead time {1e3 * model.dead_time_s:.1f} ms, "
          f"lag {1e3 * model.tau_s:.1f} ms (mean of {len(fits)} steps)")
    step = fits[0][0]
    end = lp.record_s
    times = np.array([0.5, 1.0, 1.5, 2.0, 3.0, 5.0]) * model.t63_s
    times = times[times < end]
    print(f"Step response, {step.label} (+{abs(step.amplitude):g} bar): measured vs the "
          f"model's, change in {out_unit}")
    print(f"  {'t ms':>7s} {'measured':>10s} {'predicted':>10s}")
    for t, meas, pred in predicted_vs_measured(model, step, times):
        print(f"  {1e3 * t:7.1f} {meas:10.4f} {pred:10.4f}")
    errs = [model_rms_error(model, s) for s, _ in fits]
    print(f"  the model against every step: rms error {min(errs):.4f} to {max(errs):.4f} "
          f"{out_unit}")


def print_gains(loop: str, present: Present, new: Present) -> None:
    """The new gains beside the present ones, by config key."""
    print("Gains (SIMC PI, tau_c = dead time"
          + ("; rate feedforward = dead time + lag" if loop == "pressure" else "")
          + ") and the plant they are judged against:")
    print(f"  {'key':36s} {'present':>10s} {'new':>10s} {'change':>8s}")
    for key, value in new.gains.items():  # as --save writes them
        print(change_row(".".join(key), 36, present.gains.get(key, 0.0), value))


def pyplot() -> ModuleType:
    """matplotlib.pyplot on the Agg backend, for `pamd tune --plot` (PamdError with the
    install hint when matplotlib is missing: the optional `plot` extra)."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt
    except ImportError:
        raise PamdError("--plot needs matplotlib: pip install 'pamd[plot]'") from None
    return plt


def plot_fits(path: str, lp: LoopPlan, model: Fopdt,
              fits_by_muscle: dict[str, list[tuple[StepResponse, Fopdt]]]) -> None:
    """Each step's measured response (normalised by its amplitude) and the model's."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for muscle, fits in fits_by_muscle.items():
        for s, _ in fits:
            t = s.t_s - s.t_step_s
            y0 = float(s.y[t < 0].mean())
            ax.plot(1e3 * t, (s.y - y0) / s.amplitude, lw=0.8, alpha=0.7,
                    label=f"{muscle} {s.label}")
    t = np.linspace(-0.05, lp.record_s, 800)
    ax.plot(1e3 * t, model.step_response(t), "k--", lw=2, label="model (mean)")
    ax.set_xlabel("time after the step (ms)")
    ax.set_ylabel(f"change per bar of step ({lp.unit})")
    ax.set_title(f"pamd tune: {lp.loop} loop, gain {model.gain:.3g} {lp.unit}, dead time "
                 f"{1e3 * model.dead_time_s:.1f} ms, lag {1e3 * model.tau_s:.1f} ms")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save_figure(fig, path, 120)  # whole or not at all (pamd.wire.atomic)
    plt.close(fig)
