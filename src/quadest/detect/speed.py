"""The rotor-failure detector's speed test (docs/detection.md, *The motor's speed*): with the rotor
speeds measured and the commands known, a rotor whose speed falls below what any working motor
within the model's stated errors would reach from its commands has failed (its motor stopped, its
ESC lost sync), whatever the thrust it still makes.

The lowest speed a working motor can have follows from the detector's first-order motor model,
``Ω̇ = (u − Ω) / τ``, with its time constant anywhere within ``τ / k`` to ``k τ`` and its top speed
down to ``(1 − sag) Ω_max``: the floor ``Ω_low`` rises towards ``u`` as the slowest motor would
(``k τ``) and falls towards it as the fastest (``τ / k``), so a working motor's speed stays above it
(a comparison of the two first-order equations, each sample). A reading above the floor lifts it
(less three of the reading's noise): the floor starts from what was measured.
"""

from __future__ import annotations

import numpy as np

from quadest._jit import njit
from quadest.detect.layout import MODEL, STATE
from quadest.detect.params import PARAM


@njit(cache=True, inline="always")
def speed_floor(low, cmd, p, c, dt):
    """The floor ``Ω_low`` over an interval ``dt`` with the command ``cmd`` (rad/s): towards the
    command held within ``(1 − sag)`` of the lowest and top speeds, at the slowest rise (``k τ``,
    and the rate limit over ``k``) or the fastest fall (``τ / k``, no rate limit), exactly
    (``u + (Ω − u) e^{−dt/τ}``: no overshoot however short ``τ / k`` is against ``dt``)."""
    k = p[PARAM.speed_tau_ratio]
    keep = 1.0 - p[PARAM.speed_top_sag]
    target = min(max(cmd, keep * c[MODEL.omega_min]), keep * c[MODEL.omega_max])
    if target > low:
        rise = target + (low - target) * np.exp(-dt / (k * c[MODEL.tau]))
        return min(rise, low + dt * c[MODEL.omega_dot_max] / k)
    return target + (low - target) * np.exp(-dt * k / c[MODEL.tau])


@njit(cache=True, inline="always")
def speed_test(x, p, c, rotors, dt):
    """Each rotor's shortfall below its floor, as a share of the model's top speed,
    ``s_i = (Ω_low,i − Ω_i) / Ω_max``, summed by a CUSUM ``S_i ← max(0, S_i + Δt (s_i − ν))``;
    the first past ``speed_threshold`` is lost, with the share of its thrust its speed leaves,
    ``(Ω_i / Ω_low,i)²``. Off without the commands (``STATE.cmd_known``); a missing reading
    skips its rotor's sum."""
    if p[PARAM.speed_test] == 0.0 or x[STATE.cmd_known] == 0.0:
        return
    top = c[MODEL.omega_max]
    lift = 1.0 - 3.0 * p[PARAM.speed_noise]
    for i in range(int(c[MODEL.rotors])):
        low = speed_floor(x[STATE.speed_low + i], x[STATE.cmd + i], p, c, dt)
        r = rotors[i]
        if np.isfinite(r):
            s = max(0.0, x[STATE.s_speed + i] + dt * ((low - r) / top - p[PARAM.speed_drift]))
            x[STATE.s_speed + i] = s
            if x[STATE.lost] < 0.0 and s > p[PARAM.speed_threshold]:
                x[STATE.lost], x[STATE.lost_t] = i, x[STATE.time]
                x[STATE.lost_eta] = (max(r, 0.0) / low) ** 2 if low > 0.0 else 0.0
            low = max(low, lift * r)
        x[STATE.speed_low + i] = low
