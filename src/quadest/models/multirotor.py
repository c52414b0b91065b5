"""A multirotor at rotor level: rigid body, N rotors with first-order motors, per-rotor
aerodynamics (the vehicle model that the controllers and the closed loop fly).

Conventions (:mod:`quadest.conventions`): navigation frame NED, body frame FRD, ``q_nb``, SI.
State ``x = [p_n (3), v_n (3), q_nb (4), ω_b (3), Ω (N)]`` with Ω the rotor speeds (rad/s, ≥ 0).

Rotor i sits at ``r_i`` (body, from the centre of mass) and turns about the body's ``z`` axis in
the sense ``s_i`` (+1: about +z, i.e. clockwise seen from above; −1: counter-clockwise). With
its hub's velocity relative to still air ``u_i = Rᵀ v + ω × r_i`` (body) split into an axial
part ``u_z`` (positive: the hub moves down, air enters the disc from below) and an in-plane
part ``u_⊥``:

- thrust along −z: ``T_i = η_i max(0, k_f Ω² + k_z Ω u_z)``: a rotor that climbs
  (``u_z < 0``) makes less thrust, one that descends more (a linear inflow model; idle thrust
  during a fall is not a constant);
- rotor drag (H-force) in the disc plane: ``H_i = −η_i k_h Ω u_⊥``;
- reaction torque about z: ``−s_i η_i k_m Ω²``; the forces act at ``r_i`` (moment ``r_i × F_i``);
- body drag ``−|u| C_d u`` with ``u = Rᵀ v`` and ``C_d = diag(c_x, c_y, c_z)``, rotational
  damping ``−D ω`` and rotational drag ``−C_r |ω| ω`` (per axis).

``η_i`` is rotor i's efficiency: 1 intact, between 0 and 1 a damaged rotor, 0 a lost one.
Motors: ``Ω̇ = clip((clip(Ω_cmd, Ω_min, Ω_max) − Ω)/τ, ±Ω̇_max)``.

Equations of motion: ``ṗ = v``, ``v̇ = g e_z + R F/m``, ``q̇ = ½ q ⊗ [0, ω]``,
``J ω̇ = M − ω × J ω`` (J diagonal). Integrated by :func:`rk4` (classical Runge-Kutta, the
quaternion renormalised after each step) in compiled code.

The recovery paper's reduced aerodynamic model (:mod:`quadest.models.aero`) stays the
estimator's model: it is fitted from this model's flights, never used as its truth.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import NO_ALLOCATION, njit
from quadest.conventions import GRAVITY
from quadest.errors import UsageError
from quadest.records import check, describe, param
from quadest.rotation.kernels import qdot_s, rotate_inv_s, rotate_s

Vehicle = namedtuple(
    "Vehicle",
    [
        "mass",
        "inertia",
        "rotor_pos",
        "spin",
        "k_f",
        "k_m",
        "k_z",
        "k_h",
        "tau",
        "omega_min",
        "omega_max",
        "omega_dot_max",
        "c_d",
        "damping",
        "rot_drag",
        "gravity",
        "rotor_inertia",
        "wind",
        "ground",
        "legs",
    ],
)
"""What the compiled dynamics read (built by :meth:`MultirotorParams.vehicle`): the vehicle, the
air's velocity (NED, m/s; set by the loop sample by sample) and the ground its legs may touch
(:func:`with_ground`)."""

GROUND_FIELDS = ("z", "stiffness", "damping", "friction")
"""``Vehicle.ground``'s values: the ground's height (NED z, m; inf: none), each leg's stiffness
(N/m) and damping (N s/m), and the friction coefficient."""


def with_ground(dynamics: Vehicle, z: float, *, leg_height: float = 0.05, spread: float = 0.6,
                stiffness: float = 500.0, damping: float = 5.0, friction: float = 0.5) -> Vehicle:  # fmt: skip
    """``dynamics`` standing on legs below its rotors (at ``spread`` times their horizontal
    position, ``leg_height`` below the centre of mass) over a flat ground at NED ``z``. Each leg
    in contact pushes with ``max(0, k δ + c δ̇)`` along the ground's normal (δ its depth) and
    drags with ``friction`` times that against its sliding. The values are chosen: 10 Hz on the
    Bebop 2's four legs, a damping ratio of about 0.3, so that a touchdown at ``v`` peaks near
    ``v · 63 rad/s`` (about 10 g at 1.5 m/s: a hard landing), a static deflection of 2.5 mm."""
    legs = np.array(dynamics.rotor_pos, float) * spread
    legs[:, 2] = leg_height
    return dynamics._replace(ground=np.array([z, stiffness, damping, friction], float), legs=legs)


def quad_x(arm_m: float) -> tuple:
    """Rotor positions of a quadrotor in X configuration (body FRD): front-right, rear-left,
    front-left, rear-right, at ``arm_m`` from the centre."""
    a = arm_m / np.sqrt(2.0)
    return ((a, a, 0.0), (-a, -a, 0.0), (a, -a, 0.0), (-a, a, 0.0))


@dataclass(frozen=True)
class MultirotorParams:
    """A vehicle at rotor level. Rotor order and spins: :func:`quad_x` (diagonal pairs turn the
    same way, so the yaw torques cancel in hover)."""

    mass_kg: float = param(0.5, "kg", "mass", "recovery paper, experimental setup (m = 0.5 kg)", bounds="(0, 1e3]")
    inertia: tuple = param(
        (0.0023, 0.0023, 0.0046),
        "kg m²",
        "principal moments of inertia (body axes)",
        "recovery paper, experimental setup",
    )
    rotor_pos: tuple = param(
        quad_x(0.17),
        "m",
        "rotor positions from the centre of mass (body FRD)",
        "recovery paper, experimental setup (arm L = 0.17 m), X layout chosen",
    )
    spin: tuple = param(
        (1.0, 1.0, -1.0, -1.0),
        "-",
        "rotor sense: +1 about +z (clockwise seen from above)",
        "chosen: diagonal pairs alike",
    )
    k_f: float = param(
        6.5e-6,
        "N s²",
        "thrust per squared rotor speed",
        "chosen: hover near 430 rad/s for 0.5 kg (a 5-inch propeller)",
        bounds="(0, 1]",
    )
    k_m: float = param(
        1.1e-7,
        "N m s²",
        "reaction torque per squared rotor speed",
        "chosen: k_m/k_f = 0.017 m, typical of small propellers",
        bounds="[0, 1]",
    )
    k_z: float = param(
        7e-5,
        "N s²/m",
        "thrust change per rotor speed and axial hub speed (inflow)",
        "chosen: 10 % less thrust when climbing at 4 m/s in hover",
        bounds="[0, 1]",
    )
    k_h: float = param(
        1.0e-4,
        "N s²/m",
        "rotor (H-force) drag per rotor speed and in-plane hub speed",
        "chosen: 0.17 N per rotor at 4 m/s in hover",
        bounds="[0, 1]",
    )
    motor_tau_s: float = param(
        0.02, "s", "motor time constant", "chosen: small brushless motors, 15-40 ms", bounds="(0, 10]"
    )
    omega_min: float = param(0.0, "rad/s", "lowest rotor speed (idle)", "chosen", bounds="[0, 1e4]")
    omega_max: float = param(
        900.0, "rad/s", "highest rotor speed", "chosen: thrust-to-weight about 4.4", bounds="(0, 1e4]"
    )
    omega_dot_max: float = param(
        5e4, "rad/s²", "rotor acceleration limit", "Sun et al. 2021 (their Bebop 2 simulation)", bounds="(0, 1e12]"
    )
    body_drag: tuple = param(
        (0.01, 0.01, 0.01), "N s²/m²", "quadratic body drag per body axis (x, y, z)", "chosen: 0.16 N at 4 m/s"
    )
    damping: tuple = param(
        (0.0, 0.0, 0.0),
        "N m s",
        "linear rotational damping per axis",
        "chosen: none; the body's rotational drag is quadratic (rot_drag), the rotors' drag acts through k_h",
    )
    rot_drag: tuple = param(
        (5e-5, 5e-5, 1e-4),
        "N m s²",
        "quadratic rotational drag per axis: −sign(ω) c ω²",
        "Sun et al. 2021, their Bebop 2 simulation (simParams.m, aero.rotDrag)",
    )
    gravity: float = param(GRAVITY, "m/s²", "gravity", "standard gravity", bounds="(0, 100]")
    rotor_inertia: float = param(
        0.0,
        "kg m²",
        "moment of inertia of each rotor (propeller and motor bell) about its axis",
        "chosen: none (the recovery paper gives none; its throws keep the rotors at a constant speed)",
        bounds="[0, 1e-2]",
    )
    blades: int = param(
        2,
        "-",
        "blades per propeller (the vibration's blade-pass tone; not in the dynamics)",
        "chosen: two-blade propellers, the common small-quadrotor kind",
        bounds="[1, 12]",
    )

    def __post_init__(self):
        check(self, "vehicle")
        pos = np.asarray(self.rotor_pos, float)
        if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) < 1:
            raise ValueError(f"vehicle: rotor_pos must be N rows of 3 coordinates, got shape {pos.shape}")
        if np.asarray(self.spin, float).shape != (len(pos),) or not np.isin(self.spin, (-1.0, 1.0)).all():
            raise ValueError(f"vehicle: spin must hold +1 or -1 for each of the {len(pos)} rotors")
        for name in ("inertia", "damping", "body_drag", "rot_drag"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not np.isfinite(v).all() or (v < 0).any() or (name == "inertia" and (v <= 0).any()):
                raise ValueError(
                    f"vehicle: {name} must be three {'positive' if name == 'inertia' else 'non-negative'} "
                    f"numbers, got {getattr(self, name)!r}"
                )
        if self.omega_min > self.omega_max:
            raise ValueError("vehicle: omega_min must not exceed omega_max")

    @property
    def rotors(self) -> int:
        return len(self.rotor_pos)

    def vehicle(self) -> Vehicle:
        return Vehicle(
            float(self.mass_kg),
            np.asarray(self.inertia, float),
            np.ascontiguousarray(self.rotor_pos, float),
            np.asarray(self.spin, float),
            float(self.k_f),
            float(self.k_m),
            float(self.k_z),
            float(self.k_h),
            float(self.motor_tau_s),
            float(self.omega_min),
            float(self.omega_max),
            float(self.omega_dot_max),
            np.asarray(self.body_drag, float),
            np.asarray(self.damping, float),
            np.asarray(self.rot_drag, float),
            float(self.gravity),
            float(self.rotor_inertia),
            np.zeros(3),
            np.array([np.inf, 0.0, 0.0, 0.0]),
            np.zeros((0, 3)),
        )

    def hover_speed(self) -> float:
        """Rotor speed at which N equal rotors at rest carry the weight: ``√(m g / (N k_f))``."""
        return float(np.sqrt(self.mass_kg * self.gravity / (self.rotors * self.k_f)))

    def hover_state(self) -> np.ndarray:
        """Level, at rest at the origin, rotors at the hover speed."""
        x = np.zeros(13 + self.rotors)
        x[6] = 1.0
        x[13:] = self.hover_speed()
        return x

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


_SUN = "Sun et al., T-RO 2021, public simulation (github.com/SihaoSun/INDI_Quadrotor_FTC)"
_ROTORPY = "RotorPy 3.0, rotorpy/vehicles/hummingbird_params.py"
_PPRZ = "Paparazzi's Bebop 2 INDI airframe (conf/airframes/TUDELFT/tudelft_bebop2_indi.xml)"

VEHICLE_PRESETS = {
    "recovery": ({}, {}),
    "bebop2": (
        dict(
            mass_kg=0.375,
            inertia=(0.0014, 0.0013, 0.0025),
            rotor_pos=((0.0875, 0.115, 0.0), (-0.0875, -0.115, 0.0), (0.0875, -0.115, 0.0), (-0.0875, 0.115, 0.0)),
            spin=(1.0, 1.0, -1.0, -1.0),
            k_f=1.9035e-6,
            k_m=1.9202951e-8,
            k_z=3.3e-5,
            k_h=4.05e-5,
            motor_tau_s=1.0 / 30.0,
            omega_min=0.0,
            omega_max=1200.0,
            omega_dot_max=5e4,
            body_drag=(0.01, 0.01, 0.01),
            damping=(0.0, 0.0, 0.0),
            rot_drag=(5e-5, 5e-5, 1e-4),
            gravity=9.8124,
            blades=3,
            rotor_inertia=4.7e-6,
        ),
        dict(
            mass_kg=f"{_SUN}: controlParams.m (the simulation's own mass is in a .mat file)",
            inertia=f"{_SUN}: controlParams.m",
            rotor_pos=f"{_SUN}: controlParams.m, arms l = 0.0875 m (fore-aft) and b = 0.115 m (lateral)",
            spin=f"{_SUN}: simpleAeroModel.m (front-left and rear-right turn counter-clockwise)",
            k_f=f"{_SUN}: simParams.m, aero.k0",
            k_m=f"{_SUN}: simParams.m, aero.t0",
            k_z="chosen: 10 % less thrust climbing at 4 m/s in hover (as the default vehicle)",
            k_h="chosen: linear rotor drag 0.3 1/s at hover (the simulator's rotor_drag, Faessler et al. 2018)",
            motor_tau_s=f"{_SUN}: simParams.m, actuator.t_w",
            omega_min=f"{_SUN}: simParams.m",
            omega_max=f"{_SUN}: simParams.m",
            omega_dot_max=f"{_SUN}: simParams.m, actuator.rateRise",
            body_drag="chosen: as the default vehicle",
            damping="chosen: none (the drag is quadratic)",
            rot_drag=f"{_SUN}: simParams.m, aero.rotDrag",
            gravity=f"{_SUN}: simParams.m (Delft)",
            blades="the Bebop 2's stock propellers have three blades",
            rotor_inertia=f"{_PPRZ}: the ratio of the yaw effectiveness of the rotor acceleration to "
            "that of the rotor speed, G2_R / G1_R = 0.20 / 0.0022 at 512 Hz, is I_p f / (2 k_m Ω) for the "
            "incremental yaw model; with this preset's k_m and hover speed (695 rad/s) I_p = 4.7e-6 "
            "(range: docs/vehicle.md, Spin range)",
        ),
    ),
    "hummingbird": (
        dict(
            mass_kg=0.5,
            inertia=(3.65e-3, 3.68e-3, 7.03e-3),
            rotor_pos=tuple((x, y, 0.0) for x, y, _ in quad_x(0.17)),
            spin=(-1.0, -1.0, 1.0, 1.0),
            k_f=5.57e-6,
            k_m=1.36e-7,
            k_z=2.32e-4,
            k_h=1.19e-4,
            motor_tau_s=0.005,
            omega_min=0.0,
            omega_max=1500.0,
            omega_dot_max=1e12,
            body_drag=(5e-3, 5e-3, 1e-2),
            damping=(0.0, 0.0, 0.0),
            rot_drag=(0.0, 0.0, 0.0),
            gravity=9.81,
            blades=2,
            rotor_inertia=0.0,
        ),
        dict(
            mass_kg=f"{_ROTORPY}: mass",
            inertia=f"{_ROTORPY}: Ixx, Iyy, Izz",
            rotor_pos=f"{_ROTORPY}: rotor_pos (d = 0.17 m, X), in FRD",
            spin=f"{_ROTORPY}: rotor_directions [1, -1, 1, -1] (FLU order r1..r4)",
            k_f=f"{_ROTORPY}: k_eta",
            k_m=f"{_ROTORPY}: k_m",
            k_z=f"{_ROTORPY}: k_z (induced inflow)",
            k_h=f"{_ROTORPY}: k_d (rotor drag); its translational lift k_h and flapping are not modelled here",
            motor_tau_s=f"{_ROTORPY}: tau_m",
            omega_min=f"{_ROTORPY}: rotor_speed_min",
            omega_max=f"{_ROTORPY}: rotor_speed_max",
            omega_dot_max="RotorPy has no rate limit",
            body_drag=f"{_ROTORPY}: c_Dx, c_Dy, c_Dz",
            damping="RotorPy has none",
            rot_drag="RotorPy has none",
            gravity="RotorPy: 9.81",
            blades="the AscTec Hummingbird's 8-inch propellers have two blades",
            rotor_inertia="RotorPy has none (its rotors' inertia is not modelled: the cross-check stays like for like)",
        ),
    ),
}
"""Vehicles by name: the fields that differ from :class:`MultirotorParams`' defaults (the
recovery paper's vehicle) and the source of each."""


SPIN_RANGES = {
    "bebop2": {
        "k_h": (
            (0.0, "Sun et al.'s simple aerodynamic model (simpleAeroModel.m) has no rotor drag"),
            (4.05e-5, "the preset's (chosen: Faessler et al. 2018's linear rotor drag, 0.3 1/s at hover)"),
            (
                6.1e-5,
                "RotorPy's Hummingbird rotor drag per unit mass at hover (4 k_d Ω_h / m = 0.45 1/s) on the "
                "Bebop 2: 0.45 m / (4 Ω_h)",
            ),
        ),
        "rotor_inertia": (
            (0.0, "a bound, not a measurement: no rotor inertia (quadest before; the controller models of Sun et al.)"),
            (4.7e-6, "the preset's: Paparazzi's Bebop 2 INDI airframe, G2_R / G1_R"),
            (1.1e-5, "LADAC's Bebop 2 (TU Braunschweig, LADAC_params/Bebop2/copter_params_Bebop2.m: prop.I)"),
        ),
    },
}
"""Per vehicle, the parameters that decide the spin after a rotor loss, each as ``(low, chosen,
high)`` values with their sources (docs/vehicle.md, *Spin range*)."""


def vehicle_preset(name: str) -> MultirotorParams:
    """A vehicle by name (:data:`VEHICLE_PRESETS`)."""
    if name not in VEHICLE_PRESETS:
        raise UsageError(f"unknown vehicle {name!r}; vehicles: {', '.join(VEHICLE_PRESETS)}")
    return MultirotorParams(**VEHICLE_PRESETS[name][0])


def preset_rows(name: str) -> list[dict]:
    """Every parameter of a vehicle preset with its value and source (for the docs)."""
    values, sources = VEHICLE_PRESETS[name]
    rows = []
    for row in MultirotorParams.describe():
        if row["name"] in values:
            row = {**row, "default": values[row["name"]], "source": sources[row["name"]]}
        rows.append(row)
    return rows


@njit(cache=True, **NO_ALLOCATION)
def rotor_forces(x, eta, vehicle, F, M, T):
    """Total rotor and body force ``F`` and moment ``M`` (body frame) at state ``x``, and each
    rotor's thrust ``T`` (N), in place."""
    qw, qx, qy, qz = x[6], x[7], x[8], x[9]
    w0, w1, w2 = x[10], x[11], x[12]
    wind = vehicle.wind
    ub0, ub1, ub2 = rotate_inv_s(qw, qx, qy, qz, x[3] - wind[0], x[4] - wind[1], x[5] - wind[2])
    sp = np.sqrt(ub0 * ub0 + ub1 * ub1 + ub2 * ub2)
    F[0], F[1], F[2] = -vehicle.c_d[0] * sp * ub0, -vehicle.c_d[1] * sp * ub1, -vehicle.c_d[2] * sp * ub2
    M[0] = -vehicle.damping[0] * w0 - vehicle.rot_drag[0] * abs(w0) * w0
    M[1] = -vehicle.damping[1] * w1 - vehicle.rot_drag[1] * abs(w1) * w1
    M[2] = -vehicle.damping[2] * w2 - vehicle.rot_drag[2] * abs(w2) * w2
    for i in range(vehicle.rotor_pos.shape[0]):
        r0, r1, r2 = vehicle.rotor_pos[i, 0], vehicle.rotor_pos[i, 1], vehicle.rotor_pos[i, 2]
        om = x[13 + i]
        # hub velocity: u = Rᵀ v + ω × r
        u0 = ub0 + (w1 * r2 - w2 * r1)
        u1 = ub1 + (w2 * r0 - w0 * r2)
        u2 = ub2 + (w0 * r1 - w1 * r0)
        thrust = eta[i] * max(0.0, vehicle.k_f * om * om + vehicle.k_z * om * u2)
        T[i] = thrust
        f0, f1, f2 = -eta[i] * vehicle.k_h * om * u0, -eta[i] * vehicle.k_h * om * u1, -thrust
        F[0] += f0
        F[1] += f1
        F[2] += f2
        M[0] += r1 * f2 - r2 * f1
        M[1] += r2 * f0 - r0 * f2
        M[2] += r0 * f1 - r1 * f0 - vehicle.spin[i] * eta[i] * vehicle.k_m * om * om
    if np.isfinite(vehicle.ground[0]):
        ground_contact(x, vehicle, F, M)


@njit(cache=True, inline="always")
def ground_contact(x, vehicle, F, M):
    """Add the ground's push and friction on each leg in contact (:func:`with_ground`) to the body
    force ``F`` and moment ``M``."""
    qw, qx, qy, qz = x[6], x[7], x[8], x[9]
    w0, w1, w2 = x[10], x[11], x[12]
    z, k, c, mu = vehicle.ground[0], vehicle.ground[1], vehicle.ground[2], vehicle.ground[3]
    for j in range(vehicle.legs.shape[0]):
        r0, r1, r2 = vehicle.legs[j, 0], vehicle.legs[j, 1], vehicle.legs[j, 2]
        p0, p1, p2 = rotate_s(qw, qx, qy, qz, r0, r1, r2)
        depth = x[2] + p2 - z
        if depth <= 0.0:
            continue
        v0, v1, v2 = rotate_s(qw, qx, qy, qz, w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0)
        v0, v1, v2 = v0 + x[3], v1 + x[4], v2 + x[5]
        push = max(0.0, k * depth + c * v2)
        slide = max(np.sqrt(v0 * v0 + v1 * v1), 0.05)  # smoothed: no chatter at rest
        f0, f1, f2 = rotate_inv_s(qw, qx, qy, qz, -mu * push * v0 / slide, -mu * push * v1 / slide, -push)
        F[0] += f0
        F[1] += f1
        F[2] += f2
        M[0] += r1 * f2 - r2 * f1
        M[1] += r2 * f0 - r0 * f2
        M[2] += r0 * f1 - r1 * f0


@njit(cache=True)
def derivative(x, cmd, eta, vehicle, dx):
    """``ẋ`` at ``x`` with rotor speed commands ``cmd`` (rad/s) and efficiencies ``eta``, every
    motor driven."""
    n_rot = vehicle.rotor_pos.shape[0]
    derivative_ws(x, cmd, eta, np.ones(n_rot), vehicle, dx, np.empty(3), np.empty(3), np.empty(n_rot))


@njit(cache=True, **NO_ALLOCATION)
def derivative_ws(x, cmd, eta, drive, vehicle, dx, F, M, T):
    """:func:`derivative` with each motor's ``drive`` (1: it follows its command, 0: its ESC has
    stopped driving it, :mod:`quadest.sim.faults`) and its work arrays given (no allocation in a
    hot loop); on return ``F``, ``M`` and ``T`` hold the body force, moment and rotor thrusts at ``x``."""
    rotor_forces(x, eta, vehicle, F, M, T)
    qw, qx, qy, qz = x[6], x[7], x[8], x[9]
    w0, w1, w2 = x[10], x[11], x[12]
    a0, a1, a2 = rotate_s(qw, qx, qy, qz, F[0] / vehicle.mass, F[1] / vehicle.mass, F[2] / vehicle.mass)
    dx[0], dx[1], dx[2] = x[3], x[4], x[5]
    dx[3], dx[4], dx[5] = a0, a1, a2 + vehicle.gravity
    dx[6], dx[7], dx[8], dx[9] = qdot_s(qw, qx, qy, qz, w0, w1, w2)
    h = 0.0  # the rotors' angular momentum about body z, and its rate
    h_dot = 0.0
    for i in range(vehicle.rotor_pos.shape[0]):
        target = drive[i] * min(max(cmd[i], vehicle.omega_min), vehicle.omega_max)
        rate = (target - x[13 + i]) / vehicle.tau
        dx[13 + i] = min(max(rate, -vehicle.omega_dot_max), vehicle.omega_dot_max)
        h += vehicle.rotor_inertia * eta[i] * vehicle.spin[i] * x[13 + i]
        h_dot += vehicle.rotor_inertia * eta[i] * vehicle.spin[i] * dx[13 + i]
    J0, J1, J2 = vehicle.inertia[0], vehicle.inertia[1], vehicle.inertia[2]
    # Euler: J ω̇ = M − ω × (J ω + h e_z) − ḣ e_z
    dx[10] = (M[0] - (w1 * J2 * w2 - w2 * J1 * w1) - w1 * h) / J0
    dx[11] = (M[1] - (w2 * J0 * w0 - w0 * J2 * w2) + w0 * h) / J1
    dx[12] = (M[2] - (w0 * J1 * w1 - w1 * J0 * w0) - h_dot) / J2


@njit(cache=True)
def rk4(x, cmd, eta, vehicle, h):
    """One classical Runge-Kutta step of ``h`` seconds, in place; the quaternion is renormalised
    and rotor speeds kept non-negative."""
    rk4_ws(x, cmd, eta, np.ones(vehicle.rotor_pos.shape[0]), vehicle, h, work(vehicle, x.shape[0]))


@njit(cache=True)
def work(vehicle, n):
    """Work arrays of :func:`rk4_ws`: the stages and the force, moment and thrusts."""
    return np.empty((5, n)), np.empty(3), np.empty(3), np.empty(vehicle.rotor_pos.shape[0])


@njit(cache=True, **NO_ALLOCATION)
def rk4_ws(x, cmd, eta, drive, vehicle, h, work_arrays):
    """:func:`rk4` with each motor's ``drive`` (:func:`derivative_ws`) and its work arrays
    ``work_arrays`` (from :func:`work`): no allocation per step."""
    n = x.shape[0]
    stages, F, M, T = work_arrays
    k1, k2, k3, k4, y = stages[0], stages[1], stages[2], stages[3], stages[4]
    derivative_ws(x, cmd, eta, drive, vehicle, k1, F, M, T)
    for j in range(n):
        y[j] = x[j] + 0.5 * h * k1[j]
    derivative_ws(y, cmd, eta, drive, vehicle, k2, F, M, T)
    for j in range(n):
        y[j] = x[j] + 0.5 * h * k2[j]
    derivative_ws(y, cmd, eta, drive, vehicle, k3, F, M, T)
    for j in range(n):
        y[j] = x[j] + h * k3[j]
    derivative_ws(y, cmd, eta, drive, vehicle, k4, F, M, T)
    for j in range(n):
        x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    nq = np.sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9])
    for j in range(6, 10):
        x[j] /= nq
    for i in range(13, n):
        x[i] = max(x[i], 0.0)


@njit(cache=True)
def fly_open_loop(x, cmd, eta, vehicle, h, steps, out):
    """``steps`` RK4 steps with constant commands; ``out[k]`` the state after step k."""
    work_arrays, drive = work(vehicle, x.shape[0]), np.ones(vehicle.rotor_pos.shape[0])
    for k in range(steps):
        rk4_ws(x, cmd, eta, drive, vehicle, h, work_arrays)
        for j in range(x.shape[0]):
            out[k, j] = x[j]


@njit(cache=True)
def derivatives(states, cmds, etas, vehicle, dx, thrusts):
    """``ẋ`` and the rotor thrusts along a flight (one row per step, with that step's rotor
    efficiencies), in place."""
    F = np.empty(3)
    M = np.empty(3)
    drive = np.ones(vehicle.rotor_pos.shape[0])
    for k in range(states.shape[0]):
        derivative_ws(states[k], cmds[k], etas[k], drive, vehicle, dx[k], F, M, thrusts[k])
