"""The jet algebra against finite differences of its own values."""

import numpy as np

from quadest.sim import jets
from quadest.sim.jets import Jet


def trig_jet(t, w, ph, amp):
    return Jet(amp * np.sin(w * t + ph), amp * w * np.cos(w * t + ph), -amp * w * w * np.sin(w * t + ph))


def fd_check(f, t, h=1e-4, tol=1e-6):
    """f(t) -> Jet; compare d1, d2 with central differences."""
    j0, jm, jp = f(t), f(t - h), f(t + h)
    np.testing.assert_allclose(j0.d1, (jp.v - jm.v) / (2 * h), atol=tol)
    np.testing.assert_allclose(j0.d2, (jp.v - 2 * j0.v + jm.v) / h**2, atol=100 * tol)


def vec(t):
    return jets._stack3(trig_jet(t, 1.3, 0.2, 1.0), trig_jet(t, 0.7, 1.0, 2.0), trig_jet(t, 2.1, -0.5, 0.5) + 3.0)


def test_products_and_normalize():
    t = np.linspace(0, 5, 40)
    fd_check(lambda s: jets.normalize(vec(s)), t)
    fd_check(lambda s: jets.cross(vec(s), jets.normalize(vec(s + 0.7))), t)
    fd_check(lambda s: jets.norm(vec(s)), t)
    fd_check(lambda s: jets.dot(vec(s), vec(s + 1)), t)


def test_rotation_jets_and_body_rates():
    t = np.linspace(0, 5, 40)

    def ang(s):
        return trig_jet(s, 1.1, 0.3, 2.0)

    def Rf(s):
        return jets.matmul(jets.rot_z(ang(s)), jets.rot_axis([0.6, 0.8, 0.0], trig_jet(s, 0.5, 0.0, 1.0)))

    fd_check(Rf, t)
    R = Rf(t)
    np.testing.assert_allclose(np.swapaxes(R.v, 1, 2) @ R.v, np.broadcast_to(np.eye(3), R.v.shape), atol=1e-14)
    w, wdot = jets.body_rates(R)
    h = 1e-5
    Rp, Rm = Rf(t + h).v, Rf(t - h).v
    W = np.swapaxes(R.v, 1, 2) @ (Rp - Rm) / (2 * h)
    np.testing.assert_allclose(w, jets.vee(W), atol=1e-8)
    wp, _ = jets.body_rates(Rf(t + h))
    wm, _ = jets.body_rates(Rf(t - h))
    np.testing.assert_allclose(wdot, (wp - wm) / (2 * h), atol=1e-6)
