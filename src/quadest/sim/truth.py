"""The true motion of each scenario at the sample instants.

Flight scenarios (``hover``, ``nominal``, ``damaged-rotor``) are built by differential flatness
with exact derivatives (:mod:`quadest.sim.jets`): the body z axis follows the required thrust
direction, so the accelerometer sees thrust and rotor drag as on a real quadcopter. The
``throw`` scenario is a hand motion followed by rigid-body free flight
(:mod:`quadest.sim.rigid_body`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from quadest.rotation import (
    euler_to_quat,
    matrix_to_quat,
    quat_conj,
    quat_continuous,
    quat_from_rotvec,
    quat_mul,
    quat_to_matrix,
    quat_to_rotvec,
)
from quadest.sim import jets
from quadest.sim.jets import Jet
from quadest.sim.params import SimConfig
from quadest.sim.rigid_body import integrate
from quadest.sim.sensors import motor_current
from quadest.sim.signals import RampedSinusoids, Sinusoids

PRESCRIBED_SCENARIOS = ("hover", "nominal", "damaged-rotor", "throw", "rest", "six-position", "figure-eight")
CALIBRATION_SCENARIOS = ("rest", "six-position", "figure-eight")


@dataclass
class Truth:
    """True state at the sample instants (quadest conventions, SI units)."""

    t: np.ndarray
    q: np.ndarray  # (N, 4) q_nb
    gyr: np.ndarray  # (N, 3) body rate
    gyr_dot: np.ndarray  # (N, 3) body angular acceleration
    pos: np.ndarray  # (N, 3) centre of mass, NED
    vel: np.ndarray  # (N, 3)
    acc_n: np.ndarray  # (N, 3) acceleration of the centre of mass, NED
    current: np.ndarray  # (N,) motor current over its maximum (all rotors at full thrust)
    rotor_load: np.ndarray  # (N,) thrust per active rotor over hover thrust per rotor
    meta: dict = field(default_factory=dict)
    gyr_bias: np.ndarray | None = None  # (N, 3) gyroscope bias incl. random walk (simulate(return_truth=True))
    acc_bias: np.ndarray | None = None  # (N, 3) accelerometer bias incl. random walk
    rotor_speeds: np.ndarray | None = None  # (N, rotors) rad/s, a flown vehicle's (its vibration)
    rotor_imbalance: np.ndarray | None = None  # (N, rotors) kg m, a damaged propeller's imbalance

    @classmethod
    def concat(cls, parts):
        names = ["t", "q", "gyr", "gyr_dot", "pos", "vel", "acc_n", "current", "rotor_load"]
        out = cls(**{k: np.concatenate([getattr(p, k) for p in parts]) for k in names})
        out.meta = parts[0].meta if parts else {}
        return out


def _quat(R):
    return quat_continuous(matrix_to_quat(R))


def _frame_from_z(zb: Jet, yaw: Jet) -> Jet:
    """``R_nb`` whose third column is ``zb`` and whose ZYX yaw is ``yaw`` (Mellinger & Kumar):
    ``x_b = normalize(y_c × z_b)`` with ``y_c = (-sin ψ, cos ψ, 0)``, ``y_b = z_b × x_b``."""
    zero = Jet.const(np.zeros_like(yaw.v))
    yc = jets._stack3(-jets.sin(yaw), jets.cos(yaw), zero)
    xb = jets.normalize(jets.cross(yc, zb))
    yb = jets.cross(zb, xb)
    return jets.columns(xb, yb, zb)


class FlightMotion:
    """Shared machinery: a spin-centre path and a yaw signal give the attitude by flatness."""

    def __init__(self, cfg: SimConfig):
        self.cfg = cfg
        self.g = np.array([0.0, 0.0, cfg.environment.gravity])
        self.d = cfg.vehicle.rotor_drag
        self.meta = {}

    # subclasses define path_jets(t) -> (pos, vel, acc, jerk-jets) and attitude
    def thrust_dir(self, t):
        """``u = g − a − d v``: along body z with magnitude (T/m − d z·v) for isotropic rotor
        drag (Faessler et al. 2018), so ``z_b = u/|u|`` exactly."""
        a = self.path.jet(t, 2)
        v = self.path.jet(t, 1)
        return Jet.const(np.broadcast_to(self.g, a.v.shape)) - a - v * self.d, v

    def evaluate(self, t) -> Truth:
        raise NotImplementedError

    def _truth(self, t, R: Jet, pos: Jet, thrust_spec, n_active):
        w, wdot = jets.body_rates(R)
        g = self.cfg.environment.gravity
        v = self.cfg.vehicle
        load = (thrust_spec / n_active) / (g / 4.0)
        return Truth(
            t=t,
            q=_quat(R.v),
            gyr=w,
            gyr_dot=wdot,
            pos=pos.v,
            vel=pos.d1,
            acc_n=pos.d2,
            current=motor_current(load, n_active, v.thrust_to_weight),
            rotor_load=load,
            meta=self.meta,
        )


class HoverMotion(FlightMotion):
    """Gust-disturbed hover: horizontal accelerations of ``gust_acc_rms`` RMS, slow small yaw."""

    def __init__(self, cfg, rng, duration):
        super().__init__(cfg)
        h = cfg.hover
        path = Sinusoids.random(rng, h.gust_band_hz, h.components, 3)
        path = path.scaled([1.0, 1.0, h.vertical_ratio])
        horiz = Sinusoids(path.w, path.amp * [1.0, 1.0, 0.0], path.phase)
        rms = horiz.rms(duration, k=2)
        self.path = path.scaled(h.gust_acc_rms / rms if rms > 0 else 0.0)
        self.start = np.array([0.0, 0.0, -10.0])
        yaw = Sinusoids.random(rng, h.yaw_band_hz, h.components, 1, power=0.0)
        peak = yaw.peak(duration)
        self.yaw = yaw.scaled(np.radians(h.yaw_amp_deg) / peak if peak > 0 else 0.0)
        self.yaw0 = rng.uniform(-np.pi, np.pi)

    def yaw_jet(self, t):
        y = self.yaw.jet(t)
        return Jet(y.v[:, 0] + self.yaw0, y.d1[:, 0], y.d2[:, 0])

    def evaluate(self, t):
        u, v = self.thrust_dir(t)
        zb = jets.normalize(u)
        R = _frame_from_z(zb, self.yaw_jet(t))
        pos = self.path.jet(t) + self.start
        thrust = jets.norm(u).v + self.d * np.sum(zb.v * v.v, axis=1)
        return self._truth(t, R, pos, thrust, 4)


class NominalMotion(HoverMotion):
    """Moving flight along a smooth random 3-D path (peak acceleration ``acc_max``), yaw rate up
    to ``yaw_rate_max``. The flight starts from hover: the path's acceleration ramps in from
    zero (``RampedSinusoids``), so the first samples see the vehicle at rest as a real log does."""

    def __init__(self, cfg, rng, duration):
        FlightMotion.__init__(self, cfg)
        n = cfg.nominal
        path = RampedSinusoids.random(
            rng, n.band_hz, n.components, 3, 0.0, n.ramp_s, scale_dims=[1.0, 1.0, n.vertical_ratio]
        )
        self.path = path.scaled(n.acc_max / path.peak(duration, k=2))
        self.start = np.array([0.0, 0.0, -20.0])
        yaw = Sinusoids.random(rng, n.yaw_band_hz, n.components, 1, power=1.0)
        self.yaw = yaw.scaled(n.yaw_rate_max / yaw.peak(duration, k=1))
        self.yaw0 = rng.uniform(-np.pi, np.pi)


class DamagedRotorMotion(HoverMotion):
    """Hover, then the loss of one rotor: spin-up to ``spin_rate_mean`` about a body-fixed axis
    tilted ``tilt_deg`` from body z (relaxed hover, Mueller & D'Andrea 2014).

    ``R_nb = R_axis · Rz(φ) · R_tiltᵀ`` where ``R_axis`` puts the spin axis along the required
    mean thrust direction ``n = normalize(g − a_c − d v_c)`` of the spin centre ``c`` and
    ``R_tilt = Rot(e_t, α)`` maps body z to the body-fixed spin axis ``n_b``; so
    ``ω_b = φ̇ n_b`` while the axis is steady. The tilt grows with the spin rate,
    ``α = α_f (φ̇_s/Ω̄)²``. Body z, along which the rotors push, cones around the spin axis; the
    resulting horizontal thrust ``(T/m) sin α`` turning at the spin rate moves the centre of mass
    on a circle of radius ``(T/m) α / φ̇²`` about the spin centre, which is added to the path, so
    the accelerometer reads thrust along body z as on the real vehicle.
    """

    def __init__(self, cfg, rng, duration):
        HoverMotion.__init__(self, cfg, rng, duration)
        dm = cfg.damaged
        self.tf = dm.failure_s
        man = RampedSinusoids.random(
            rng, dm.manoeuvre_band_hz, cfg.hover.components, 3, self.tf, dm.spin_up_tau_s, scale_dims=[1.0, 1.0, 0.3]
        )
        peak = man.peak(max(duration, self.tf + 1.0), k=2)
        self.man = man.scaled(dm.manoeuvre_acc_max / peak)
        var = Sinusoids.random(rng, dm.spin_band_hz, cfg.hover.components, 1, power=0.0)
        peak = var.peak(max(duration, self.tf + 1.0), t0=self.tf)
        self.var = var.scaled(dm.spin_rate_var / peak)
        self.Om = dm.spin_rate_mean
        self.tau = dm.spin_up_tau_s
        self.alpha_f = np.radians(dm.tilt_deg)
        az = np.radians(dm.tilt_azimuth_deg)
        self.e_tilt = np.array([np.cos(az), np.sin(az), 0.0])
        # R_tiltᵀ e3 = cos α e3 + sin α w, with w the unit body-horizontal direction below
        self.w_perp = np.array([-np.sin(az), np.cos(az), 0.0])
        self.sign = float(np.sign(dm.spin_sign) or 1.0)
        self.n_active = dm.active_rotors
        self.meta = {"failure_time_s": self.tf}

    def ramp(self, t):
        """Spin-up ``s = 1 − exp(−(t − t_f)/τ)`` after the failure, 0 before: (s, ṡ, s̈)."""
        x = np.maximum(t - self.tf, 0.0)
        on = t >= self.tf
        e = np.exp(-x / self.tau)
        return np.where(on, 1 - e, 0.0), np.where(on, e / self.tau, 0.0), np.where(on, -e / self.tau**2, 0.0)

    def spin(self, t):
        """Spin angle φ_s and its first three derivatives, analytic (including the integral)."""
        s, s1, s2 = self.ramp(t)
        w, A, p = self.var.w, self.var.amp[:, 0], self.var.phase[:, 0]
        arg = np.outer(t, w) + p
        Om = self.Om + np.sin(arg) @ A
        Om1 = np.cos(arg) @ (A * w)
        Om2 = -np.sin(arg) @ (A * w**2)
        x = np.maximum(t - self.tf, 0.0)
        on = t >= self.tf
        # ∫_tf^t s(τ') Ω(τ') dτ', with s = 1 − exp(−x/τ): the constant, the sinusoids, and the
        # sinusoids times the exponential ∫_0^x e^{−x'/τ} sin(w x' + θ) dx' = Im[e^{iθ} (e^{(iw−1/τ)x} − 1)/(iw − 1/τ)]
        th = w * self.tf + p
        phi = self.Om * (x - self.tau * (1 - np.exp(-x / self.tau)))
        i1 = (np.cos(th)[None, :] - np.cos(arg)) / w
        lam = 1j * w - 1.0 / self.tau
        i2 = np.imag(np.exp(1j * th)[None, :] * (np.exp(np.outer(x, lam)) - 1.0) / lam)
        phi = phi + (i1 - i2) @ A
        phi = np.where(on, phi, 0.0)
        return (
            self.sign * phi,
            self.sign * s * Om,
            self.sign * (s1 * Om + s * Om1),
            self.sign * (s2 * Om + 2 * s1 * Om1 + s * Om2),
        )

    def evaluate(self, t):
        s, s1, s2 = self.ramp(t)
        ramp = Jet(s, s1, s2)

        # spin-centre path: the hover gusts plus manoeuvres that start from rest at the failure
        def centre(k0):
            return self.path.jet(t, k0) + self.man.jet(t, k0)

        pc, vc, ac = centre(0), centre(1), centre(2)
        u = Jet.const(np.broadcast_to(self.g, ac.v.shape)) - ac - vc * self.d
        n_axis = jets.normalize(u)
        R_axis = _frame_from_z(n_axis, Jet.const(np.full(len(t), self.yaw0)))
        ph, ph1, ph2, ph3 = self.spin(t)
        yaw_h = self.yaw.jet(t)
        phi = Jet(ph + yaw_h.v[:, 0], ph1 + yaw_h.d1[:, 0], ph2 + yaw_h.d2[:, 0])
        k = self.alpha_f / self.Om**2
        alpha = Jet(k * ph1**2, 2 * k * ph1 * ph2, 2 * k * (ph2**2 + ph1 * ph3))
        R_tilt = jets.rot_axis(self.e_tilt, alpha)
        Rspin = jets.matmul(R_axis, jets.rot_z(phi))
        R = jets.matmul(Rspin, jets.transpose(R_tilt))
        # centre of mass on its small circle about the spin centre: δ = (|u| α_f/Ω̄²) s h
        h = jets.matvec(Rspin, Jet.const(np.broadcast_to(self.w_perp, (len(t), 3))))
        c = jets.scale(jets.norm(u), ramp) * k
        pos = pc + jets.scale(c, h) + self.start
        thrust = jets.norm(u).v / np.cos(alpha.v)
        return self._truth(t, R, pos, thrust, np.where(t >= self.tf, self.n_active, 4))


def _smoothstep(x):
    """S(x) = 3x² − 2x³ on [0, 1] (0 before, 1 after), its integral and derivatives."""
    x = np.clip(x, 0.0, 1.0)
    inside = (x > 0) & (x < 1)
    S = 3 * x**2 - 2 * x**3
    integral = x**3 - 0.5 * x**4
    S1 = np.where(inside, 6 * x - 6 * x**2, 0.0)
    S2 = np.where(inside, 6 - 12 * x, 0.0)
    return integral, S, S1, S2


def uniform_quaternion(rng):
    """A rotation drawn uniformly on SO(3) (normalised 4-D Gaussian)."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def _uniform_direction(rng):
    d = rng.normal(size=3)
    return d / np.linalg.norm(d)


class ThrowMotion:
    """Held in the hand, thrown, released with a random state, then free flight.

    Release state: attitude uniform on SO(3), velocity of uniform direction over the upper
    hemisphere (any direction with ``any_direction``) and speed in ``[0, speed_max]``,
    body rate of uniform direction and magnitude in ``[0, rate_max]``. The
    hand motion before release is a smooth ramp of velocity ``v0 S(x)`` and body rate
    ``ω0 S(x)`` over ``throw_s`` (S the smoothstep), after ``hold_s`` held still with a small
    tremor, so that the release state is reached continuously. Propellers idle throughout; the
    free flight is integrated with RK4 (:mod:`quadest.sim.rigid_body`).
    """

    def __init__(self, cfg: SimConfig, rng, duration):
        self.cfg = cfg
        th = cfg.throw
        self.t_release = th.hold_s + th.throw_s
        self.q_r = uniform_quaternion(rng)
        d = _uniform_direction(rng)
        if not th.any_direction and d[2] > 0.0:  # upward or horizontal: no down component (NED)
            d[2] = -d[2]
        self.v0 = d * rng.uniform(0.0, th.speed_max)
        self.w0 = _uniform_direction(rng) * rng.uniform(0.0, th.rate_max)
        self.p_r = np.array([0.0, 0.0, -th.release_height_m])
        tremor = Sinusoids.random(rng, (3.0, 8.0), 3, 3)
        self.tremor = tremor.scaled(th.tremor_acc / max(tremor.peak(1.0, k=2), 1e-12))
        a = cfg.aero
        self.A, self.B, self.C = (np.array(a.A, float), np.array(a.B, float), np.array(a.C, float))
        v = cfg.vehicle
        self.m, self.Jd, self.Dd = v.mass_kg, np.array(v.inertia, float), np.array(a.rate_damping, float)
        self.g = np.array([0.0, 0.0, cfg.environment.gravity])
        self.idle = -self.C[2, 9] / self.m  # idle specific thrust, m/s² (up the body)
        self.state = None  # free-flight state carried between chunks: (t, x)
        self.meta = {
            "release_time_s": self.t_release,
            "release_q": self.q_r.tolist(),
            "release_vel": self.v0.tolist(),
            "release_gyr": self.w0.tolist(),
        }

    def release_state(self):
        x = np.zeros(13)
        x[0:3], x[3:6], x[6:10], x[10:13] = self.p_r, self.v0, self.q_r, self.w0
        return x

    def _hand(self, t) -> Truth:
        T = self.cfg.throw.throw_s
        x = (t - (self.t_release - T)) / T
        integral, S, S1, S2 = _smoothstep(x)
        sigma = Jet(T * (integral - 0.5), S, S1 / T)  # ∫ S: zero at release
        hold = Jet(1 - S, -S1 / T, -S2 / T**2)  # tremor fades out during the throw
        pos = jets.scale(sigma, Jet.const(np.broadcast_to(self.v0, (len(t), 3)))) + self.p_r
        pos = pos + jets.scale(hold, self.tremor.jet(t))
        wn = np.linalg.norm(self.w0)
        axis = self.w0 / wn if wn > 0 else np.array([0.0, 0.0, 1.0])
        Rr = Jet.const(np.broadcast_to(quat_to_matrix(self.q_r), (len(t), 3, 3)))
        R = jets.matmul(Rr, jets.rot_axis(axis, sigma * wn))
        n = len(t)
        return Truth(
            t=t,
            q=_quat(R.v),
            gyr=np.outer(S, self.w0),
            gyr_dot=np.outer(S1 / T, self.w0),
            pos=pos.v,
            vel=pos.d1,
            acc_n=pos.d2,
            current=self._current(n),
            rotor_load=self._load(n),
            meta=self.meta,
        )

    def _current(self, n):
        return np.full(n, motor_current(self._load(1)[0], 4, self.cfg.vehicle.thrust_to_weight))

    def _load(self, n):
        return np.full(n, self.idle / self.cfg.environment.gravity)

    def _flight(self, t) -> Truth:
        if self.state is None:
            self.state = (self.t_release, self.release_state())
        t0, x0 = self.state
        X, dX = integrate(
            x0, t0, t, self.cfg.throw.max_step_s, self.m, self.Jd, self.Dd, self.A, self.B, self.C, self.g
        )
        self.state = (t[-1], X[-1].copy())
        n = len(t)
        return Truth(
            t=t,
            q=quat_continuous(X[:, 6:10]),
            gyr=X[:, 10:13],
            gyr_dot=dX[:, 10:13],
            pos=X[:, 0:3],
            vel=X[:, 3:6],
            acc_n=dX[:, 3:6],
            current=self._current(n),
            rotor_load=self._load(n),
            meta=self.meta,
        )

    def evaluate(self, t) -> Truth:
        hand = t < self.t_release
        parts = []
        if hand.any():
            parts.append(self._hand(t[hand]))
        if (~hand).any():
            parts.append(self._flight(t[~hand]))
        return Truth.concat(parts)


class CalibrationMotion:
    """Hand-held calibration motions with the motors off (no vibration, no motor current); the
    position is fixed, so the accelerometer reads gravity plus its lever-arm terms.

    - ``rest``: a fixed attitude (level, random heading).
    - ``six-position``: each body axis pointing down and up in turn (z down, z up, x up, x down,
      y up, y down), held ``hold_s``, turned over ``turn_s`` by a smooth rotation; each placement
      may be off by ``six_tilt_deg`` about a random axis.
    - ``figure-eight``: heading sweeping full turns while roll and pitch swing by ``tilt_amp_deg``
      at incommensurate rates, so the body axes visit every direction (for the magnetometer's
      ellipsoid fit).
    """

    def __init__(self, scenario, cfg: SimConfig, rng, duration):
        self.cfg = cfg
        self.kind = scenario
        c = cfg.calibration
        self.yaw0 = rng.uniform(-np.pi, np.pi)
        self.pos = np.array([0.0, 0.0, -1.0])
        self.meta = {"motors": "off"}
        if scenario == "six-position":
            base = [(0.0, 0.0), (np.pi, 0.0), (0.0, np.pi / 2), (0.0, -np.pi / 2), (-np.pi / 2, 0.0), (np.pi / 2, 0.0)]
            qs = []
            for roll, pitch in base:
                q = euler_to_quat([roll, pitch, self.yaw0])
                if c.six_tilt_deg > 0:
                    ax = rng.normal(size=3)
                    q = quat_mul(quat_from_rotvec(np.radians(c.six_tilt_deg) * ax / np.linalg.norm(ax)), q)
                qs.append(q)
            self.quats = qs
            self.hold, self.turn = c.hold_s, c.turn_s
            # the body axis that points down or up in each position (pitch +90°: nose up)
            self.meta["positions"] = ["z down", "z up", "x up", "x down", "y up", "y down"]
            self.meta["segments_s"] = [
                [k * (self.hold + self.turn), k * (self.hold + self.turn) + self.hold] for k in range(6)
            ]

    def evaluate(self, t) -> Truth:
        n = len(t)
        if self.kind == "rest":
            R = Jet.const(np.broadcast_to(quat_to_matrix(euler_q(0.0, 0.0, self.yaw0)), (n, 3, 3)))
        elif self.kind == "figure-eight":
            c = self.cfg.calibration
            wy = 2 * np.pi / c.figure8_period_s
            A = np.radians(c.tilt_amp_deg)
            yaw = Jet(self.yaw0 + wy * t, np.full(n, wy), np.zeros(n))
            wp, wr = wy * 1.618, wy * 2.414
            pitch = Jet(A * np.sin(wp * t), A * wp * np.cos(wp * t), -A * wp * wp * np.sin(wp * t))
            roll = Jet(A * np.sin(wr * t + 0.7), A * wr * np.cos(wr * t + 0.7), -A * wr * wr * np.sin(wr * t + 0.7))
            R = jets.matmul(
                jets.matmul(jets.rot_z(yaw), jets.rot_axis([0, 1, 0], pitch)), jets.rot_axis([1, 0, 0], roll)
            )
        else:  # six-position
            period = self.hold + self.turn
            k = np.clip((t // period).astype(int), 0, 5)
            x = np.clip((t - k * period - self.hold) / self.turn, 0.0, 1.0)
            x = np.where(k >= 5, 0.0, x)
            integral, S, S1, S2 = _smoothstep(x)
            Rs = np.empty((n, 3, 3))
            axis = np.zeros((n, 3))
            ang = np.zeros(n)
            for j in range(6):
                sel = k == j
                if not sel.any():
                    continue
                q0 = self.quats[j]
                q1 = self.quats[min(j + 1, 5)]
                rv = quat_to_rotvec(quat_mul(quat_conj(q0), q1))
                a = np.linalg.norm(rv)
                Rs[sel] = quat_to_matrix(q0)
                axis[sel] = rv / a if a > 0 else np.array([0.0, 0.0, 1.0])
                ang[sel] = a
            th = Jet(ang * S, ang * S1 / self.turn, ang * S2 / self.turn**2)
            # per-sample axis: Rodrigues with the jet of the angle (axis constant within a turn)
            c_, s_ = jets.cos(th), jets.sin(th)
            K = np.zeros((n, 3, 3))
            K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
            K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
            KK = K @ K
            rot = (
                Jet.const(np.broadcast_to(np.eye(3), (n, 3, 3)))
                + jets.scale(s_, Jet.const(K))
                + jets.scale(1.0 - c_, Jet.const(KK))
            )
            R = jets.matmul(Jet.const(Rs), rot)
        w, wdot = jets.body_rates(R)
        zeros = np.zeros((n, 3))
        return Truth(
            t=t,
            q=_quat(R.v),
            gyr=w,
            gyr_dot=wdot,
            pos=np.broadcast_to(self.pos, (n, 3)).copy(),
            vel=zeros.copy(),
            acc_n=zeros.copy(),
            current=np.zeros(n),
            rotor_load=np.zeros(n),
            meta=self.meta,
        )


def euler_q(roll, pitch, yaw):
    return euler_to_quat([roll, pitch, yaw])


def make_motion(scenario: str, cfg: SimConfig, rng, duration: float):
    """The motion model of a scenario (its random draws come from ``rng``)."""
    if scenario in CALIBRATION_SCENARIOS:
        return CalibrationMotion(scenario, cfg, rng, duration)
    cls = {
        "hover": HoverMotion,
        "nominal": NominalMotion,
        "damaged-rotor": DamagedRotorMotion,
        "throw": ThrowMotion,
    }.get(scenario)
    if cls is None:
        raise ValueError(f"unknown scenario {scenario!r}; scenarios: {', '.join(PRESCRIBED_SCENARIOS)}")
    return cls(cfg, rng, duration)


def default_duration(scenario: str, cfg: SimConfig) -> float:
    c = cfg.calibration
    if scenario == "rest":
        return c.rest_s
    if scenario == "six-position":
        return 6 * c.hold_s + 5 * c.turn_s
    if scenario == "figure-eight":
        return c.figure8_s
    sec = {"hover": cfg.hover, "nominal": cfg.nominal, "damaged-rotor": cfg.damaged, "throw": cfg.throw}[scenario]
    return sec.duration_s
