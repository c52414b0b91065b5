"""A vehicle identified from its own nominal flights with measured rotor speeds (docs/vehicle.md,
*Your own vehicle*).

Every signal is put on a uniform grid and low-passed alike (a zero-phase Butterworth filter:
the equations below are linear in the signals, so they hold between the filtered ones); the
angular acceleration is the filtered gyroscope's derivative. Least squares, no intercepts:

- specific force along body z: ``f_z = −(k_f/m) Σ Ω_i²``;
- roll and pitch: ``ω̇_x = Σ a_i Ω_i² + g_x ω_y ω_z + h_x ω_y Σ s_i Ω_i + D_x f_xy`` (pitch alike
  with ``ω_x``): the body's and the rotors' gyroscopic moments and the drag's, with
  ``a_i = −(k_f/J_x) y_i`` and ``b_i = (k_f/J_y) x_i`` (rotor i at ``(x_i, y_i)`` from the
  centre of mass); the signs of ``a_i`` and ``b_i`` place each rotor (its numbering), and with
  the rotors at the corners of a square of the given arm about the rotors' centre, their spread
  gives ``k_f/J`` and their mean the centre of mass off the rotors' centre (the steady thrust
  split: in hover the rotors nearer the centre of mass carry more);
- yaw: ``ω̇_z = Σ c_i Ω_i² − (I_r/J_z) Σ s_i Ω̇_i + e_1 ω_z Σ Ω_i + e_2 |ω_z| ω_z + D_z f_xy``
  with ``c_i = −(k_m/J_z) s_i``: the sign of ``c_i`` gives rotor i's sense ``s_i``, the second
  term the rotors' inertia where observable, then the rotors' and the body's drag as it turns.

Absolute mass, inertia and arm are not identifiable from these signals: the fit gives the
per-mass and per-inertia quantities, and the vehicle is stated at a reference mass and arm the
user gives (a unit mass and arm by default). Uncertainties are the spread of the same fit on
``BLOCKS`` contiguous parts of the samples, over √BLOCKS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

from quadest.errors import UsageError

BLOCKS = 6
"""Parts the samples are split into for the uncertainties."""
RATE_HZ = 200.0
"""The uniform grid's rate (Hz): above the telemetry's 100 Hz, below the IMU's."""
CUTOFF_HZ = 8.0
"""The low-pass's cut-off (Hz): the rigid body's moments, not the frame's vibration."""
EDGE_S = 1.0
"""Seconds left out at each end of a flying span (take-off, landing, the filter's start)."""
FLYING_SHARE = 0.5
"""A row flies when its summed squared rotor speed is above this share of the flight's median."""


@dataclass
class Samples:
    """Flying rows of one or more flights on a uniform grid, low-passed alike: rotor speeds
    (rad/s), their squares (rad²/s²) and rates (rad/s²), body rates (rad/s), angular accelerations (rad/s²),
    the specific force (m/s², body), and each row's flight."""

    speed: np.ndarray
    speed2: np.ndarray
    speed_dot: np.ndarray
    gyr: np.ndarray
    alpha: np.ndarray
    f: np.ndarray
    flight: np.ndarray

    def __len__(self) -> int:
        return len(self.f)

    def rows(self, keep) -> Samples:
        return Samples(*(getattr(self, k)[keep] for k in self.__dataclass_fields__))

    @staticmethod
    def joined(parts) -> Samples:
        return Samples(*(np.concatenate([getattr(p, k) for p in parts]) for k in Samples.__dataclass_fields__))


def _spans(mask) -> list[tuple[int, int]]:
    """``[start, end)`` of each run of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def flight_samples(rec, index: int = 0, name: str = "recording", *, rate_hz: float = RATE_HZ,
                   cutoff_hz: float = CUTOFF_HZ) -> Samples:  # fmt: skip
    """A recording's flying rows (:data:`FLYING_SHARE`, :data:`EDGE_S`) as :class:`Samples`
    (``name``: the file, for messages)."""
    if rec.rotor_speed is None:
        raise UsageError(f"{name}: no rotor speeds (rotor_speed): identify needs each rotor's measured speed")
    speed = np.asarray(rec.rotor_speed, float)
    ok = np.isfinite(speed).all(axis=1) & np.isfinite(rec.gyr).all(axis=1) & np.isfinite(rec.acc).all(axis=1)
    total = (speed**2).sum(axis=1)
    if not ok.any():
        raise UsageError(f"{name}: no row with every rotor's speed, gyroscope and accelerometer")
    flying = ok & (total > FLYING_SHARE * np.median(total[ok]))
    t = np.asarray(rec.t, float)
    sos = butter(2, cutoff_hz, fs=rate_hz, output="sos")
    parts = []
    for a, b in _spans(flying):
        t0, t1 = t[a] + EDGE_S, t[b - 1] - EDGE_S
        if t1 - t0 < 2.0:
            continue
        grid = np.arange(t0, t1, 1.0 / rate_hz)
        on_grid = [_on_grid(grid, t[a:b], v[a:b]) for v in (speed, rec.gyr, rec.acc)]
        sp, gyr, acc = (sosfiltfilt(sos, v, axis=0) for v in on_grid)
        sp2 = sosfiltfilt(sos, on_grid[0] ** 2, axis=0)  # the squares filtered: the equations stay linear
        dt = 1.0 / rate_hz
        rates = np.gradient(sp, dt, axis=0)
        parts.append(Samples(sp, sp2, rates, gyr, np.gradient(gyr, dt, axis=0), acc, np.full(len(grid), index)))
    if not parts:
        raise UsageError(f"{name}: no flying span of {2.0 + 2 * EDGE_S:.0f} s or more (rotors above half their median)")
    return Samples.joined(parts)


def _on_grid(grid, t, v) -> np.ndarray:
    """Each column of ``v`` (rows at ``t``) interpolated at ``grid``."""
    return np.column_stack([np.interp(grid, t, v[:, j]) for j in range(v.shape[1])])


def _lsq(X, y) -> np.ndarray:
    return np.linalg.lstsq(X, y, rcond=None)[0]


def moment_regressors(s: Samples, axis: int, spin=None) -> np.ndarray:
    """The columns of the roll (``axis`` 0) or pitch (1) fit (module doc): the squared speeds, the
    body's gyroscopic product, given the senses the rotors' momentum's (``ω_y Σ s_i Ω_i`` for
    roll, ``ω_x Σ s_i Ω_i`` for pitch), then the specific force along x and y (the drag's
    moments); the yaw fit's (axis 2) are :func:`yaw_regressors`."""
    if axis == 2:
        return yaw_regressors(s, spin)
    w = s.gyr
    body = w[:, 1] * w[:, 2] if axis == 0 else w[:, 0] * w[:, 2]
    rotors = [] if spin is None else [w[:, 1 - axis] * (s.speed @ np.asarray(spin, float))]
    return np.column_stack([s.speed2, body, *rotors, s.f[:, 0], s.f[:, 1]])


def yaw_regressors(s: Samples, spin) -> np.ndarray:
    """The yaw fit's columns: ``Σ s_i Ω_i²`` (the reaction torque), ``Σ s_i Ω̇_i`` (the rotors'
    inertia), ``ω_z Σ Ω_i`` (the rotors' drag as the body turns), ``|ω_z| ω_z`` (the body's), and
    the specific force along x and y."""
    spin = np.asarray(spin, float)
    w = s.gyr[:, 2]
    return np.column_stack([s.speed2 @ spin, s.speed_dot @ spin, w * s.speed.sum(axis=1), np.abs(w) * w, s.f[:, :2]])


@dataclass
class Fit:
    """One fit of :class:`Samples` (module doc): ``k_f/m`` (m/s² per rad²/s²), the per-rotor
    roll, pitch and yaw coefficients (rad/s² per rad²/s²), the rotors' senses, ``I_r/J_z``, the
    drag's moments (rad/s² per m/s² of specific force along x and y, one row per axis) and each
    axis's coefficients in its regressors' order (:func:`moment_regressors`)."""

    thrust_per_mass: float
    roll: np.ndarray
    pitch: np.ndarray
    yaw: np.ndarray
    spin: np.ndarray
    rotor_inertia_per_jz: float
    drag: np.ndarray
    columns: tuple

    def coefficients(self, axis: int) -> np.ndarray:
        """Axis ``axis``'s coefficients in :func:`moment_regressors`' column order."""
        return self.columns[axis]


def diagonal_pattern(roll, pitch) -> np.ndarray:
    """±1 per rotor, alike on each diagonal of a quadrotor X (rotors placed by the signs of their
    roll and pitch coefficients): the one spin pattern up to its sign."""
    qx, qy = np.sign(pitch - pitch.mean()), -np.sign(roll - roll.mean())
    return qx * qy


def fit(s: Samples, spin=None) -> Fit:
    """The least-squares fit of the module doc. The senses, unless given, from the yaw moment
    of the one diagonal pattern (:func:`diagonal_pattern`) of a first roll and pitch fit without
    the rotors' momentum: ``ω̇_z = −(k_m/J_z) Σ s_i Ω_i² ...``."""
    n = s.speed2.shape[1]
    total = s.speed2.sum(axis=1)
    k = -float(total @ s.f[:, 2] / (total @ total))
    if spin is None:
        roll, pitch = (_lsq(moment_regressors(s, axis), s.alpha[:, axis]) for axis in (0, 1))
        pattern = diagonal_pattern(roll[:n], pitch[:n])
        spin = -np.sign(_lsq(yaw_regressors(s, pattern), s.alpha[:, 2])[0]) * pattern
    spin = np.asarray(spin, float)
    columns = tuple(_lsq(moment_regressors(s, axis, spin), s.alpha[:, axis]) for axis in range(3))
    roll, pitch, yaw = columns
    drag = np.array([roll[-2:], pitch[-2:], yaw[-2:]])
    return Fit(k, roll[:n], pitch[:n], yaw[0] * spin, spin, float(-yaw[1]), drag, columns)


def residuals(f: Fit, s: Samples) -> dict:
    """The fit's residuals on ``s`` (root mean square): the specific force along z (m/s²) and the
    angular acceleration about each axis (rad/s²), beside the signals' own spread."""
    total = s.speed2.sum(axis=1)
    out = {"f_z": _rms(s.f[:, 2] + f.thrust_per_mass * total), "f_z_spread": float(np.std(s.f[:, 2]))}
    for axis, name in enumerate(("roll", "pitch", "yaw")):
        r = s.alpha[:, axis] - moment_regressors(s, axis, f.spin) @ f.coefficients(axis)
        out[f"alpha_{name}"] = _rms(r)
        out[f"alpha_{name}_spread"] = float(np.std(s.alpha[:, axis]))
    return out


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


@dataclass
class Geometry:
    """The rotors placed from a fit: each rotor's quadrant (x forward, y right: ±1), ``k_f/J``
    about x and y (rad/s² per (rad/s)² and per metre of lever), and the centre of mass from the
    rotors' centre (m), for an arm ``arm_m``."""

    quadrant: np.ndarray
    k_over_j: np.ndarray
    com: np.ndarray
    arm_m: float

    def positions(self) -> np.ndarray:
        """Rotor positions from the centre of mass (m, body FRD, z = 0)."""
        xy = self.quadrant * self.arm_m / np.sqrt(2.0) - self.com
        return np.column_stack([xy, np.zeros(len(xy))])


def geometry(f: Fit, arm_m: float) -> Geometry:
    """Rotors at the corners of a square of arm ``arm_m`` about their centre: ``b_i = (k_f/J_y)
    (X_i − c_x)``, ``a_i = −(k_f/J_x)(Y_i − c_y)`` with ``X_i, Y_i = ±arm/√2`` (module doc)."""
    half = arm_m / np.sqrt(2.0)
    qx = np.sign(f.pitch - f.pitch.mean())
    qy = -np.sign(f.roll - f.roll.mean())
    ky = float(f.pitch @ (qx * half) / (len(qx) * half**2))
    kx = float(-(f.roll @ (qy * half)) / (len(qy) * half**2))
    com = np.array([-f.pitch.mean() / ky, f.roll.mean() / kx])
    return Geometry(np.column_stack([qx, qy]), np.array([kx, ky]), com, arm_m)


def check_layout(g: Geometry, spin, where: str, stated: dict | None = None) -> None:
    """Refuse, in one line naming the rotors, a layout that is not a quadrotor X with diagonal
    pairs alike, or one that contradicts the frame the log states (``meta['rotors']``)."""
    quadrants = {tuple(q) for q in g.quadrant.astype(int)}
    if len(g.quadrant) != 4 or len(quadrants) != 4:
        raise UsageError(
            f"{where}: the roll and pitch moments place the rotors at {g.quadrant.astype(int).tolist()} "
            "(front +1, right +1): not one rotor per corner of a quadrotor X"
        )
    for i in range(4):
        j = int(np.flatnonzero((g.quadrant == -g.quadrant[i]).all(axis=1))[0])
        if spin[i] != spin[j]:
            raise UsageError(
                f"{where}: rotors {i} and {j} sit across from each other but the yaw moments give them opposite "
                "senses: a quadrotor X turns its diagonal pairs alike"
            )
    if stated and "positions" in stated:
        wrong = [i for i in range(4) if (np.sign(stated["positions"][i][:2]) != g.quadrant[i]).any()]
        if wrong:
            raise UsageError(
                f"{where}: the log places rotor(s) {', '.join(map(str, wrong))} elsewhere than their roll and pitch "
                f"moments do ({[g.quadrant[i].astype(int).tolist() for i in wrong]}, front +1, right +1): is the "
                "motor numbering right?"
            )
    if stated and "spin" in stated:
        wrong = [i for i in range(4) if int(stated["spin"][i]) != int(spin[i])]
        if wrong:
            said = [stated["spin"][i] for i in wrong]
            raise UsageError(
                f"{where}: the log states rotor(s) {', '.join(map(str, wrong))} turn {said} (+1 clockwise), the "
                f"yaw moments say {[int(spin[i]) for i in wrong]}: is the motor numbering right?"
            )


@dataclass
class Identification:
    """What :func:`identify` found: the fit on every training flight, the rotors' places, each
    quantity's uncertainty (:data:`BLOCKS`), the held-out residuals (:func:`residuals`, one dict
    per held-out flight) and the reference mass and arm the vehicle is stated at."""

    fit: Fit
    geometry: Geometry
    uncertainty: dict
    held_out: dict
    mass_kg: float
    files: list
    speed_max: float

    def summary(self) -> dict:
        """The identified quantities by name, with their units (``{name: (value, sd, unit)}``)."""
        f, g, u = self.fit, self.geometry, self.uncertainty
        return {
            "thrust_per_mass": (f.thrust_per_mass, u["thrust_per_mass"], "m/s² per (rad/s)²"),
            "roll_gain": (g.k_over_j[0] * g.arm_m, u["roll_gain"], "rad/s² per (rad/s)² at the arm"),
            "pitch_gain": (g.k_over_j[1] * g.arm_m, u["pitch_gain"], "rad/s² per (rad/s)² at the arm"),
            "yaw_gain": (float(np.mean(np.abs(f.yaw))), u["yaw_gain"], "rad/s² per (rad/s)²"),
            "com_x": (g.com[0], u["com_x"], "m"),
            "com_y": (g.com[1], u["com_y"], "m"),
            "rotor_inertia_per_jz": (f.rotor_inertia_per_jz, u["rotor_inertia_per_jz"], "1 (I_r/J_z)"),
        }


def _derived(f: Fit, arm_m: float) -> dict:
    g = geometry(f, arm_m)
    return {
        "thrust_per_mass": f.thrust_per_mass,
        "roll_gain": g.k_over_j[0] * arm_m,
        "pitch_gain": g.k_over_j[1] * arm_m,
        "yaw_gain": float(np.mean(np.abs(f.yaw))),
        "com_x": g.com[0],
        "com_y": g.com[1],
        "rotor_inertia_per_jz": f.rotor_inertia_per_jz,
    }


def block_uncertainty(s: Samples, spin, arm_m: float, blocks: int = BLOCKS) -> dict:
    """Each derived quantity's standard error: the spread of the fit on ``blocks`` contiguous
    parts of ``s`` (the senses held), over √blocks."""
    parts = np.array_split(np.arange(len(s)), blocks)
    values = [_derived(fit(s.rows(p), spin), arm_m) for p in parts]
    return {k: float(np.std([v[k] for v in values], ddof=1) / np.sqrt(blocks)) for k in values[0]}


def identify(train: dict, held_out: dict | None = None, *, mass_kg: float = 1.0, arm_m: float = 1.0) -> Identification:
    """A quadrotor identified from the recordings ``train`` (``{file name: Recording}`` with
    rotor speeds; module doc), checked on ``held_out`` (none: each training flight left out in
    turn and predicted by the fit on the others, when there are two or more)."""
    if not train:
        raise UsageError("identify: no recording to fit")
    for name, v in (("--mass", mass_kg), ("--arm", arm_m)):
        if not (np.isfinite(v) and v > 0):
            raise UsageError(f"identify: {name} {v:g} must be a positive number")
    names = list(train)
    samples = [flight_samples(r, i, name) for i, (name, r) in enumerate(train.items())]
    for name, s in zip(names, samples):
        if s.speed2.shape[1] != 4:
            raise UsageError(f"{name}: {s.speed2.shape[1]} rotors; identify handles quadrotors (4)")
    every = Samples.joined(samples)
    f = fit(every)
    g = geometry(f, arm_m)
    where = ", ".join(names)
    check_layout(g, f.spin, where, _stated_frame(train.values()))
    held = {}
    if held_out:
        for name, r in held_out.items():
            held[name] = residuals(f, flight_samples(r, 0, name))
    elif len(samples) > 1:
        for k, s in enumerate(samples):
            others = Samples.joined([o for j, o in enumerate(samples) if j != k])
            held[names[k]] = residuals(fit(others, f.spin), s)
    top = float(np.sqrt(every.speed2.max()))
    return Identification(f, g, block_uncertainty(every, f.spin, arm_m), held, mass_kg, names, top)


def _stated_frame(recs) -> dict | None:
    """The frame a log states (``meta['rotors']`` with spin directions), if any."""
    for r in recs:
        rotors = r.meta.get("rotors") or {}
        if "spin" in rotors:
            return rotors
    return None


def identified_vehicle(ident: Identification, *, mass_given: bool = False, arm_given: bool = False):
    """The identified vehicle as :class:`~quadest.models.multirotor.MultirotorParams` at the
    reference mass and arm, with each field's source, its uncertainty and the identified
    quantities themselves (what :func:`~quadest.models.vehicle_file.write_vehicle` takes).
    ``J_z = J_x + J_y`` (a flat vehicle) is assumed: only ``k_m/J_z`` is identified."""
    f, g, u, m = ident.fit, ident.geometry, ident.uncertainty, ident.mass_kg
    fit_from = "identified (quadest identify) from " + ", ".join(ident.files)
    k_f = f.thrust_per_mass * m
    jx, jy = k_f / g.k_over_j[0], k_f / g.k_over_j[1]
    jz = jx + jy
    yaw_gain = float(np.mean(np.abs(f.yaw)))
    observed = f.rotor_inertia_per_jz > 2.0 * u["rotor_inertia_per_jz"]
    mass_src = "given (--mass)" if mass_given else "unit reference mass: mass is not identifiable from flight (--mass)"
    arm_src = f"arm {g.arm_m:g} m {'given (--arm)' if arm_given else '(unit reference arm: not identifiable; --arm)'}"
    values = {
        "mass_kg": m,
        "inertia": (jx, jy, jz),
        "rotor_pos": tuple(tuple(float(v) for v in p) for p in g.positions()),
        "spin": tuple(float(v) for v in f.spin),
        "k_f": k_f,
        "k_m": jz * yaw_gain,
        "k_z": 0.0,
        "k_h": 0.0,
        "omega_max": float(min(1e4, 1.2 * ident.speed_max)),
        "body_drag": (0.0, 0.0, 0.0),
        "rot_drag": (0.0, 0.0, 0.0),
        "rotor_inertia": jz * f.rotor_inertia_per_jz if observed else 0.0,
    }
    sources = {
        "mass_kg": mass_src,
        "inertia": f"{fit_from}: k_f / (k_f/J_x), k_f / (k_f/J_y) at the {arm_src}; J_z = J_x + J_y assumed",
        "rotor_pos": f"{fit_from}: quadrants from the roll and pitch moments' signs, centre of mass from "
        f"their mean, rotors on a square of {arm_src}",
        "spin": f"{fit_from}: the sign of the yaw moment of the diagonal pattern",
        "k_f": f"{fit_from}: specific force along z against Σ Ω² (k_f/m) times the mass",
        "k_m": f"{fit_from}: yaw moment per Σ s Ω² (k_m/J_z) times J_z",
        "k_z": "not identified (0)",
        "k_h": "not identified (0): the drag's moments are fitted apart, not used by the model",
        "omega_max": "1.2 times the highest measured rotor speed of the flights",
        "body_drag": "not identified (0)",
        "rot_drag": "not identified (0)",
        "rotor_inertia": f"{fit_from}: yaw moment per Σ s Ω̇ (I_r/J_z) times J_z"
        if observed
        else f"not observable in {', '.join(ident.files)} (I_r/J_z below twice its uncertainty): 0",
    }
    uncertainty = {"k_f": u["thrust_per_mass"] * m}
    identified = {
        name: {"value": float(v), "unit": unit, "source": fit_from, "uncertainty": float(sd)}
        for name, (v, sd, unit) in ident.summary().items()
    }
    identified["drag_moment"] = {
        "value": [[float(v) for v in row] for row in f.drag[:2]],
        "unit": "rad/s² per m/s²",
        "source": f"{fit_from}: roll's (first row) and pitch's angular acceleration against the specific force "
        "along x and y (the drag acting off the centre of mass; the detector's model takes it)",
    }
    for key in ("f_z", "alpha_roll", "alpha_pitch", "alpha_yaw"):
        if ident.held_out:
            identified[f"held_out_{key}"] = {
                "value": [round(r[key], 4) for r in ident.held_out.values()],
                "unit": "m/s²" if key == "f_z" else "rad/s²",
                "source": "root mean square residual on the held-out flights " + ", ".join(ident.held_out),
            }
    return values, sources, uncertainty, identified
