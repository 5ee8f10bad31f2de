"""The fixed-step Runge-Kutta-Nyström method (RKN4), compiled; it knows only :mod:`.problem`.

RKN4 (Abramowitz & Stegun 25.5.20, the seed's method with errata 1 and 2 corrected) for
q̈ = f(t, q, q̇), f constant-load on each piece of the load history; every piece gets a whole
number of equal steps (⌈ℓ/step⌉), so every load edge is a step boundary (seed-notes erratum 5).

    k1 = f(t, q, v)
    k2 = f(t + h/2, q + h v/2 + h² k1/8, v + h k1/2)
    k3 = f(t + h/2, q + h v/2 + h² k1/8, v + h k2/2)
    k4 = f(t + h,   q + h v + h² k3/2,   v + h k3)
    q⁺ = q + h v + h² (k1 + k2 + k3)/6,   v⁺ = v + h (k1 + 2 k2 + 2 k3 + k4)/6

The energy flows of :func:`.problem.power` (the work done on the system W and the
dissipated energy E, with rates P and D at each stage) are integrated with the velocity's
weights, W⁺ = W + h (P1 + 2 P2 + 2 P3 + P4)/6 and likewise E: the quadrature of a function of
(t, q, q̇) that the update of q̇ is for f, so of the same order 4.

Every ``STABILITY_CHECK_EVERY`` steps the step is checked against the stability region of the
locally linearized problem (:func:`check_stability`, below with its constants; the Python
driver of :mod:`reduced.integrators` applies the same rule).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._options import NO_RUNTIME
from .problem import acceleration, observation_size, observe, power, stop_margin

# statuses (shared with the Python wrapper, reduced.integrators)
OK, NONFINITE, SPEED, UNSTABLE, FAILED = 0, 2, 3, 4, 5

# RKN4 applied to y'' = λ_1,2-mode of the linearized problem has the stability function of
# classical RK4, R(z) = 1 + z + z²/2 + z³/6 + z⁴/24; a decaying mode needs |R(hλ)| ≤ 1.
STABILITY_CHECK_EVERY = 50  # steps between linearized stability checks
# Growth per step beyond the exact one that is refused. Round-off in the differenced
# Jacobian puts an undamped mode at Re(hλ) ~ 1e-10 on the seed; RK4 just outside its
# imaginary interval (|hω| = 2√2 (1 + 1e-4)) already amplifies by 1 + 2e-4.
STABILITY_MARGIN = 1e-6
# A mode with Re(hλ) above GROWING (relative to |hλ|; round-off gives ~1e-10) grows in the
# problem itself; RK4 reproduces |e^{hλ}| only to O(|hλ|⁵) (on the seed at h = 4 ms a local mode
# hλ = 0.169 + 0.224j has |R| above e^{0.169} by ~1e-5), so such a mode is refused only when the
# method grows it GROWTH_EXCESS (10 %) per step faster than the problem does.
GROWING = 1e-6
GROWTH_EXCESS = 0.1


@njit(cache=True, error_model="numpy")
def rk4_amplification(z):
    """|R(z)| of classical RK4 (and of RKN4 on a linear problem)."""
    return abs(1.0 + z + z * z / 2.0 + z * z * z / 6.0 + z * z * z * z / 24.0)


@njit(cache=True, error_model="numpy")
def amplification_limit(z):
    """The largest |R(z)| allowed for the mode z = hλ: 1 + STABILITY_MARGIN where the mode does
    not grow in the problem, |e^z| (1 + GROWTH_EXCESS) where it does (Re z > GROWING |z|)."""
    if z.real > GROWING * abs(z):
        return math.exp(min(z.real, 700.0)) * (1.0 + GROWTH_EXCESS)
    return 1.0 + STABILITY_MARGIN


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def check_stability(problem, chart, load, t, q, v, h, info):
    """0 if every mode of the linearization at (q, v) is inside RK4's stability region (or
    grows no faster in the method than in the problem); else UNSTABLE with info[1:5] =
    (Re hλ, Im hλ, |R|, limit), or FAILED when f cannot be evaluated. Uses 3 evaluations.

    The Jacobian of (q, q̇) ↦ (q̇, f) is [[0, 1], [f_q, f_q̇]] (one-sided differences); its
    modes solve λ² − f_q̇ λ − f_q = 0.
    """
    f0 = acceleration(problem, chart, load, t, q, v)
    dq = 1e-7 * max(1.0, abs(q))
    dv = 1e-7 * max(1.0, abs(v))
    fq = acceleration(problem, chart, load, t, q + dq, v)
    fv = acceleration(problem, chart, load, t, q, v + dv)
    if not (math.isfinite(f0) and math.isfinite(fq) and math.isfinite(fv)):
        return FAILED
    f_q = (fq - f0) / dq
    f_v = (fv - f0) / dv
    disc = complex(f_v * f_v + 4.0 * f_q)
    root = disc ** 0.5
    for lam in (0.5 * (f_v + root), 0.5 * (f_v - root)):
        z = h * lam
        amplification = rk4_amplification(z)
        limit = amplification_limit(z)
        if amplification > limit:
            info[1], info[2], info[3], info[4] = z.real, z.imag, amplification, limit
            return UNSTABLE
    return OK


@njit(cache=True, error_model="numpy")
def rkn4_chart(problem, chart, edges, loads, t0, q0, v0, step, speed_limit, stability, use_stop, info):
    """Integrate one chart from t0 to edges[-1]; the load history is loads[k] on
    [edges[k], edges[k+1]] (pieces before t0 are skipped, the one holding t0 starts there).

    Returns (status, stopped, t, q, v, a, observed, energy, n_steps, n_evaluations): the samples
    (each piece's first sample repeats the previous piece's last time, with q̈ on the new side),
    what ``observe`` recorded at each (m, observation_size) and the work done and the energy
    dissipated since t0 (m, 2) (J, by the quadrature in the module docstring); stopped
    when stop_margin fell to ≤ 0 after a step (the run ends at that step). On failure,
    info[0] is the time.
    """
    tf = edges[-1]
    first = 0
    while first < len(loads) - 1 and edges[first + 1] <= t0:
        first += 1
    total = 0
    for k in range(first, len(loads)):
        start = max(edges[k], t0)
        if edges[k + 1] > start:
            total += 1 + max(1, int(math.ceil((edges[k + 1] - start) / step - 1e-9)))
    ts = np.empty(total)
    qs = np.empty(total)
    vs = np.empty(total)
    accs = np.empty(total)
    obs = np.empty((total, observation_size(problem)))
    energy = np.empty((total, 2))
    work, dissipated = 0.0, 0.0
    n_samples = 0
    n_steps = 0
    n_eval = 0
    q, v = q0, v0
    if not (math.isfinite(q) and math.isfinite(v)):
        info[0] = t0
        return NONFINITE, False, ts[:0], qs[:0], vs[:0], accs[:0], obs[:0], energy[:0], 0, 0
    if abs(v) > speed_limit:
        info[0], info[1] = t0, v
        return SPEED, False, ts[:0], qs[:0], vs[:0], accs[:0], obs[:0], energy[:0], 0, 0
    for k in range(first, len(loads)):
        start = max(edges[k], t0)
        end = edges[k + 1]
        if end <= start:
            continue
        load = loads[k]
        n = max(1, int(math.ceil((end - start) / step - 1e-9)))
        h = (end - start) / n
        accel = acceleration(problem, chart, load, start, q, v)
        p1, d1 = power(problem, chart, load, v)
        n_eval += 1
        if not math.isfinite(accel):
            info[0] = start
            return (FAILED, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                    obs[:n_samples], energy[:n_samples], n_steps, n_eval)
        ts[n_samples], qs[n_samples], vs[n_samples], accs[n_samples] = start, q, v, accel
        observe(problem, chart, obs[n_samples])
        energy[n_samples, 0], energy[n_samples, 1] = work, dissipated
        n_samples += 1
        for m in range(n):
            t = start + m * h
            if stability and n_steps % STABILITY_CHECK_EVERY == 0:
                status = check_stability(problem, chart, load, t, q, v, h, info)
                n_eval += 3
                if status != OK:
                    info[0] = t
                    return (status, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                            obs[:n_samples], energy[:n_samples], n_steps, n_eval)
            k1 = accel
            qh = q + 0.5 * h * v + h * h * k1 / 8.0
            v2 = v + 0.5 * h * k1
            k2 = acceleration(problem, chart, load, t + 0.5 * h, qh, v2)
            p2, d2 = power(problem, chart, load, v2)
            v3 = v + 0.5 * h * k2
            k3 = acceleration(problem, chart, load, t + 0.5 * h, qh, v3)
            p3, d3 = power(problem, chart, load, v3)
            v4 = v + h * k3
            k4 = acceleration(problem, chart, load, t + h, q + h * v + 0.5 * h * h * k3, v4)
            p4, d4 = power(problem, chart, load, v4)
            if not (math.isfinite(k2) and math.isfinite(k3) and math.isfinite(k4)):
                info[0] = t
                return (FAILED, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                        obs[:n_samples], energy[:n_samples], n_steps, n_eval)
            q, v = (q + h * v + h * h * (k1 + k2 + k3) / 6.0,
                    v + h * (k1 + 2.0 * k2 + 2.0 * k3 + k4) / 6.0)
            work += h * (p1 + 2.0 * p2 + 2.0 * p3 + p4) / 6.0
            dissipated += h * (d1 + 2.0 * d2 + 2.0 * d3 + d4) / 6.0
            t_next = end if m + 1 == n else start + (m + 1) * h
            if not (math.isfinite(q) and math.isfinite(v)):
                info[0] = t_next
                return (NONFINITE, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                        obs[:n_samples], energy[:n_samples], n_steps, n_eval)
            if abs(v) > speed_limit:
                info[0], info[1] = t_next, v
                return (SPEED, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                        obs[:n_samples], energy[:n_samples], n_steps, n_eval)
            accel = acceleration(problem, chart, load, t_next, q, v)  # also the next step's k1
            p1, d1 = power(problem, chart, load, v)
            n_eval += 4
            n_steps += 1
            if not math.isfinite(accel):
                info[0] = t_next
                return (FAILED, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                        obs[:n_samples], energy[:n_samples], n_steps, n_eval)
            ts[n_samples], qs[n_samples], vs[n_samples], accs[n_samples] = t_next, q, v, accel
            observe(problem, chart, obs[n_samples])
            energy[n_samples, 0], energy[n_samples, 1] = work, dissipated
            n_samples += 1
            if use_stop and stop_margin(problem, chart, t_next, q, v) <= 0.0:
                return (OK, True, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples],
                        obs[:n_samples], energy[:n_samples], n_steps, n_eval)
    return (OK, False, ts[:n_samples], qs[:n_samples], vs[:n_samples], accs[:n_samples], obs[:n_samples],
            energy[:n_samples], n_steps, n_eval)
