"""Consistency of the contact estimator (deltafmi.physics.estimation.ContactEKF): the normalised
estimation error squared (NEES) of the wrist force over seeded Monte Carlo runs against its
chi-square interval.

Each run draws what the filter's model says is random, so that a consistent filter's error has
the covariance it reports: the wrist force a random walk (force_rate_std, a N(0, force_rate_std^2 T)
step at every sample, held over the sample period as the filter's prediction holds it; the first
value from the prior N(0, force_std0^2)) and the servo-angle noise (y_std). The robot is the DAE
integrated independently (solve_ivp, DOP853, rtol 1e-10) under a joint PD about its start with
gravity compensation, sampled at 1 kHz; the filter gets the noisy angles and the torques, and runs
its process model's compiled kernels, as ContactEstimator's FMU does (the Python ones give the same
bits: tests/builder/test_native_models.py, tests/models/test_contact_estimator.py). The
truth has no model error, so the filter's white acceleration noise (acceleration_std, which stands
for model errors) is set to zero: with the default 0.05 m/s^2 per sqrt(Hz) the force NEES comes
out lower (printed), under-confident, as it must when the filter allows for errors the truth lacks.

The test (Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and Navigation",
2001, section 5.4.2): for a consistent filter the force error e_k of each run is N(0, P_k), so
e' P^-1 e is chi-square with 3 degrees of freedom, and its mean over R independent runs at one
instant is chi-square(3 R) / R. Its two-sided 95 % interval is [chi2.ppf(0.025, 3 R),
chi2.ppf(0.975, 3 R)] / R; at every instant the mean NEES falls inside with probability 0.95.
The instants of one run are correlated, so the share inside is itself uncertain: asserted >= 85 %
of the instants after the first 0.1 s (where the prior's position and velocity uncertainty,
larger than the truth's, has been replaced by the data), and the mean over the instants within
the interval too (a filter whose error is consistently too large or too small fails both).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.stats import chi2

from deltafmi.physics import delta as d
from deltafmi.physics.estimation import ContactEKF, ContactEKFSettings

P = d.RL5
T = 1e-3
SERVOS = [0, 3, 6]
DEFAULT_ACCELERATION = ContactEKFSettings().acceleration_std
RUNS = 20
STEPS = 300
SETTINGS = ContactEKFSettings(contact_threshold=1e9, force_rate_std=20.0, force_std0=5.0, acceleration_std=0.0,
                              position_std0=3e-5, velocity_std0=1e-3)


@pytest.fixture(scope="module")
def kernels():
    """ContactEstimator's process kernels, compiled (C generated from their Python)."""
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.contact_estimator import ContactEstimator
    from deltafmi.runtime.native_functions import register_library

    assert use_compiled_functions(ContactEstimator)
    try:
        compiled = ContactEstimator().native_functions
    finally:
        register_library(ContactEstimator, None)
    assert compiled.compiled
    return compiled


def monte_carlo_run(seed: int, kernels) -> np.ndarray:
    """The force NEES at every sample of one seeded run (2, STEPS): of the filter with SETTINGS and,
    on the same data, of one with the default acceleration_std (printed, for comparison)."""
    rng = np.random.default_rng(seed)
    q0 = d.inverse_kinematics(P, [0.05, 0.0, -1.0])
    y_ref, x = q0[SERVOS].copy(), np.r_[q0, np.zeros(9)]
    force = SETTINGS.force_std0 * rng.standard_normal(3)
    filters, nees = [], []
    for k in range(STEPS):
        if k:
            force = force + SETTINGS.force_rate_std * np.sqrt(T) * rng.standard_normal(3)
        y = x[SERVOS] + SETTINGS.y_std * rng.standard_normal(3)
        u = d.holding_torque(P, x[:9])[0] + 800.0 * (y_ref - y) - 40.0 * x[[9, 12, 15]]
        if not filters:
            filters = [ContactEKF(P, s, y, kernels=kernels)
                       for s in (SETTINGS, replace(SETTINGS, acceleration_std=DEFAULT_ACCELERATION))]
        row = []
        for ekf in filters:
            e = ekf.step(y, u).force - force
            row.append(e @ np.linalg.solve(ekf.P[18:21, 18:21], e))
        nees.append(row)
        x = solve_ivp(lambda t, s: d.state_derivative(P, s, u, force), (0.0, T), x, method="DOP853", rtol=1e-10,
                      atol=1e-13).y[:, -1]
    return np.array(nees).T


def test_wrist_force_nees_is_within_its_chi_square_interval(kernels):
    nees = np.array([monte_carlo_run(100 + r, kernels) for r in range(RUNS)])  # (runs, filter, instant)
    mean, default = nees[:, :, int(0.1 / T):].mean(axis=0)  # per instant, over the runs
    lo, hi = chi2.ppf(0.025, 3 * RUNS) / RUNS, chi2.ppf(0.975, 3 * RUNS) / RUNS
    inside = np.mean((mean >= lo) & (mean <= hi))
    print(f"\nforce NEES over {RUNS} runs: mean {mean.mean():.3f}, from {mean.min():.3f} to {mean.max():.3f}; "
          f"95 % interval [{lo:.3f}, {hi:.3f}]; {100 * inside:.1f} % of the instants inside; with the default "
          f"acceleration_std {DEFAULT_ACCELERATION} the mean is {default.mean():.3f}")
    assert lo <= mean.mean() <= hi
    assert inside >= 0.85
