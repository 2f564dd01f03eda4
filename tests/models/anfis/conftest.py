"""Shared set-up for the pamd.models.anfis tests: single-threaded BLAS, small fixtures, a
short recorded run."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: threaded BLAS is slower

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from tests.once import once_per_run  # noqa: E402

# DMSP-20 static force fit from shared/reference/rig-physics.md:
# F = (a p + b) e^(c k) + (e p + f) k + g p + h, p in bar, k = contraction in %.
_A, _B, _C = -10.1206, 236.3164, -0.3378
_E, _F, _G, _H = -7.9242, -1.8549, 263.2552, -238.7719


def dmsp20_force_n(p_bar: np.ndarray, k_pct: np.ndarray) -> np.ndarray:
    ek = np.exp(_C * k_pct)
    return (_A * p_bar + _B) * ek + (_E * p_bar + _F) * k_pct + _G * p_bar + _H


@pytest.fixture
def inverse_data() -> tuple[np.ndarray, np.ndarray]:
    """(force_n, contraction_pct) -> pressure_bar samples of the smooth DMSP-20 fit."""
    rng = np.random.default_rng(7)
    p = rng.uniform(0.0, 6.0, 600)
    k = rng.uniform(0.0, 20.0, 600)
    return np.c_[dmsp20_force_n(p, k), k], p


def make_model(
    mf_type: str,
    n_mfs: tuple[int, ...],
    seed: int = 0,
    slope_range: tuple[float, float] = (0.7, 3.0),
):
    """A hand-built model on [0, 1]^d (identity scaling), jittered MFs, random consequents."""
    from pamd.models.anfis import AnfisModel, Variable

    rng = np.random.default_rng(seed)
    d = len(n_mfs)
    centres = [np.linspace(0.0, 1.0, m) + rng.uniform(-0.05, 0.05, m) for m in n_mfs]
    widths = [rng.uniform(0.2, 0.4, m) for m in n_mfs]
    slopes = [rng.uniform(*slope_range, m) for m in n_mfs] if mf_type == "bell" else None
    n_rules = int(np.prod(n_mfs))
    return AnfisModel(
        [Variable(f"x{i + 1}", "u", 0.0, 1.0) for i in range(d)],
        Variable("y", "v", -5.0, 5.0),
        mf_type=mf_type,
        scaling="minmax",
        scale_offset=np.zeros(d),
        scale_span=np.ones(d),
        centres=centres,
        widths=widths,
        slopes=slopes,
        consequents=rng.normal(size=(n_rules, d + 1)),
    )


@pytest.fixture
def model_factory():
    return make_model


@pytest.fixture
def dmsp20_force():
    """F(p_bar, k_pct) in N of the smooth DMSP-20 fit."""
    return dmsp20_force_n


@pytest.fixture(scope="session")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`pamd run --record` of two 0.2 Hz 0.5-5 bar sine cycles (virtual clock, ~1 s):
    exactly one MCAP file, recorded once per run for the modules that read it (none
    writes it; tests/once.py)."""
    def build(d: Path) -> str:
        r = subprocess.run([sys.executable, "-m", "pamd", "run", "--clock", "virtual",
                            "--profile", "sine", "--freq-hz", "0.2", "--min-bar", "0.5",
                            "--max-bar", "5", "--cycles", "2", "--record", str(d), "--name",
                            "sweep"],
                           capture_output=True, text=True, timeout=120,
                           cwd=Path(__file__).resolve().parents[2])
        assert r.returncode == 0, r.stderr
        files = sorted(d.glob("*.mcap"))
        assert len(files) == 1
        return str(files[0])

    return Path(once_per_run(tmp_path_factory, "anfis-recording", build))
