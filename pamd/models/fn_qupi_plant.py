"""An identified FN-QUPI model as a plant: its forward model (pressure history and load
-> length) one sample at a time, for a simulated muscle whose mechanics it stands for
(`pamd.sim.model_plant`, the sim driver's `plant_model` option).

Seed 003 runs its tracking controllers (Tables 5-7) against the identified model: the
controlled system (the FN-QUPI model) computes the displacement from the pressure the
controller asks for. `FnQupiStepper` is that model as `FnQupiModel.displacement` runs
it over a whole sequence, sample by sample: the QUPI operators' memory (reset at the
first pressure, as `Qupi.operators` starts), then the NARMAX network fed its own past
outputs (its first `Structure.start` samples the QUPI output itself, as `simulate`
starts). Its lags count samples, so it steps at the period of the samples it was
identified on (`sample_period_s`, from the model file: `provenance.fit.sample_period_s`).
Pressures outside the identified range are held to it, as `static_displacement` holds
them.
"""

from __future__ import annotations

import numpy as np

from pamd.models.fn_qupi import FnQupiModel
from pamd.models.fn_qupi_narmax import HOLD_HI, HOLD_LO
from pamd.models.registry import load_model
from pamd.wire.errors import ModelError


class FnQupiStepper:
    """The FN-QUPI forward model sample by sample (see the module doc)."""

    def __init__(self, model: FnQupiModel, sample_period_s: float) -> None:
        if not sample_period_s > 0:
            raise ModelError("fn-qupi plant: the sample period must be > 0 s")
        self.model = model
        self.sample_period_s = float(sample_period_s)
        q, st = model.qupi, model.structure
        self._q, self._st = q, st
        self._w = q.weights.ravel()
        self._nb_ops = q.r2.size
        W, wo, act = st.unpack(model.theta[None, :])
        self._W, self._wo = W[0], wo[0]
        self._a, self._b, self._c = (float(v) for v in act[0])
        self._z = np.zeros(self._w.size)
        self._past_y = np.zeros(st.na)
        self._past_f = np.zeros(st.nb + 1)
        self._past_m = np.zeros(st.nc + 1)
        self._k = 0

    def reset(self) -> None:
        """Forget the history: the next `step` is a run's first sample."""
        self._k = 0

    def step(self, pressure_bar: float, load_kg: float) -> float:
        """The length (mm) after one more sample at this pressure and load."""
        q, st = self._q, self._st
        x = min(max(pressure_bar, q.x0), q.xm)
        L, U = q.envelopes(np.array([x]))
        lower, upper = np.repeat(L[0], self._nb_ops), np.tile(U[0], q.r1.size)
        if self._k == 0:
            self._z = lower.copy()
        self._z = np.minimum(upper, np.maximum(lower, self._z))
        f = (float(self._z @ self._w) + q.q * x + q.c - st.y_lo) / st.y_span
        m = load_kg / st.m_span
        first = self._k == 0
        self._past_f = _push(self._past_f, f, first)
        self._past_m = _push(self._past_m, m, first)
        if self._k < st.start:
            y = f  # the network starts from the QUPI output (`simulate`)
        else:
            inputs = np.concatenate([self._past_y, self._past_f, self._past_m])
            s = inputs @ self._W
            y = float(np.sum(self._wo * (self._a * s * s + self._b * s + self._c)))
            y = min(max(y, HOLD_LO), HOLD_HI)
        if st.na:
            self._past_y = _push(self._past_y, y, first)
        self._k += 1
        return self.model.length_ref_mm - (st.y_lo + st.y_span * y)


def _push(history: np.ndarray, value: float, fill: bool) -> np.ndarray:
    """[value, history[0], ...] (newest first); `fill`: every entry the value (a run's
    start, as `lagged` pads with the first sample)."""
    if fill:
        return np.full(history.size, value)
    out = np.empty_like(history)
    out[0] = value
    out[1:] = history[:-1]
    return out


def plant_model(path: str) -> FnQupiStepper:
    """The model file at `path` as a plant: an fn-qupi model that states the period of
    the samples it was identified on."""
    model = load_model(path)
    if not isinstance(model, FnQupiModel):
        raise ModelError(f"{path}: a plant model must be an fn-qupi model (its forward "
                         f"model gives the length from the pressure and the load); this is "
                         f"a {model.kind} model")
    fit = model.provenance.get("fit")
    period = fit.get("sample_period_s") if isinstance(fit, dict) else None
    if not isinstance(period, (int, float)) or not period > 0:
        raise ModelError(f"{path}: the file does not state the period of the samples it "
                         "was identified on (provenance.fit.sample_period_s), which the "
                         "network's lags count in; train it from recordings with pamd "
                         "train --kind fn-qupi")
    return FnQupiStepper(model, float(period))
