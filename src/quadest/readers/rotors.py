"""The rotors of autopilot logs: each motor's command and speed on the IMU's rows (a Recording's
``rotor_speed`` and ``motor_command``, docs/readers.md), the frames the logs state (motor
numbering, arms, spin directions), and the motor outputs' ranges that ``diagnose`` reads too."""

from __future__ import annotations

import math

import numpy as np

RPM = math.pi / 30.0
"""rpm to rad/s."""
HOLD_S = 0.5
"""A reading stands on the IMU's rows until the next one, at most this long (s): a gap longer
than this leaves the rows without a reading (NaN)."""

# ArduPilot's motor tables (AP_MotorsMatrix): per motor, the arm's angle from forward (degrees,
# positive towards the right) and its sense seen from above (+1 clockwise, -1 counter-clockwise)
ARDUPILOT_FRAMES = {
    (1, 0): ("quad plus", [(90, -1), (-90, -1), (0, 1), (180, 1)]),
    (1, 1): ("quad X", [(45, -1), (-135, -1), (-45, 1), (135, 1)]),
    (2, 0): ("hexa plus", [(0, 1), (180, -1), (-120, 1), (60, -1), (-60, -1), (120, 1)]),
    (2, 1): ("hexa X", [(90, 1), (-90, -1), (-30, 1), (150, -1), (30, -1), (-150, 1)]),
}
PX4_QUAD_X = [(45, -1), (-135, -1), (-45, 1), (135, 1)]  # PX4's quad X numbering, as ArduPilot's


def frame_geometry(angles_spins) -> tuple[np.ndarray, np.ndarray]:
    """Unit-arm rotor positions (x forward, y right) and senses from (angle, sense) pairs."""
    a = np.radians([x[0] for x in angles_spins])
    return np.column_stack([np.cos(a), np.sin(a)]), np.array([float(x[1]) for x in angles_spins])


def px4_geometry(params, notes):
    """Rotors from PX4's control allocation (CA_ROTORi_PX/PY, CA_ROTORi_KM > 0 counter-clockwise);
    older logs without it are taken as quad X."""
    n = int(params.get("CA_ROTOR_COUNT", 0))
    if n == 0:
        notes.append("no CA_ROTOR parameters (PX4 before 1.13): the frame taken as quad X")
        return PX4_QUAD_X, "quad X (assumed)"
    table = []
    for i in range(n):
        x, y = float(params.get(f"CA_ROTOR{i}_PX", 0.0)), float(params.get(f"CA_ROTOR{i}_PY", 0.0))
        table.append((np.degrees(np.arctan2(y, x)), -1 if float(params.get(f"CA_ROTOR{i}_KM", 0.05)) > 0 else 1))
    return table, f"{n} rotors (CA_ geometry)"


def motor_channels(params, n, notes) -> list[int]:
    """ArduPilot's output channel (RCOU column, 1-based) of each motor: the one whose
    SERVOn_FUNCTION is 32 + motor at the log's start (33 is motor 1); without those parameters,
    channel k is motor k."""
    by_function = {int(v): int(k[5:-9]) for k, v in params.items() if k.startswith("SERVO") and k.endswith("_FUNCTION")}
    channels = [by_function.get(32 + k) for k in range(1, n + 1)]
    if None in channels:
        notes.append("motor outputs not all named by SERVOn_FUNCTION: channel k taken as motor k")
        return list(range(1, n + 1))
    return channels


def ardupilot_pwm_range(params) -> tuple[float, float]:
    """The motors' PWM range (µs): ``MOT_PWM_MIN`` / ``MAX``, else the throttle channel's (as
    ArduPilot does)."""
    lo, hi = params.get("MOT_PWM_MIN", 0.0), params.get("MOT_PWM_MAX", 0.0)
    if lo <= 0 or hi <= lo:
        lo, hi = params.get("RC3_MIN", 1000.0), params.get("RC3_MAX", 2000.0)
    return float(lo), float(hi)


def px4_pwm_range(params) -> tuple[float, float]:
    """The motors' PWM range (µs) of a PX4 log: ``PWM_MIN`` / ``MAX`` (older) or the first main
    output's ``PWM_MAIN_MIN1`` / ``MAX1``."""
    lo = float(params.get("PWM_MIN", params.get("PWM_MAIN_MIN1", 1000)))
    hi = float(params.get("PWM_MAX", params.get("PWM_MAIN_MAX1", 2000)))
    return lo, hi


def pwm_share(pwm, lo, hi) -> np.ndarray:
    """A PWM output (µs) as its share of the range ``[lo, hi]``, clipped to [0, 1]: the motor's
    normalised command."""
    return np.clip((np.asarray(pwm, float) - lo) / (hi - lo), 0.0, 1.0)


def on_rows(t, t_src, values, hold_s: float = HOLD_S) -> np.ndarray:
    """Readings ``values`` (rows at the times ``t_src``, each column its own: NaN where a column
    has no reading) on the rows ``t``: each column's latest reading at or before the row, NaN
    before its first and where it is older than ``hold_s``."""
    t, t_src, values = np.asarray(t, float), np.asarray(t_src, float), np.asarray(values, float)
    out = np.full((len(t), values.shape[1]), np.nan)
    for j in range(values.shape[1]):
        ok = np.isfinite(values[:, j]) & np.isfinite(t_src)
        ts, v = t_src[ok], values[ok, j]
        if not len(ts):
            continue
        order = np.argsort(ts, kind="stable")
        ts, v = ts[order], v[order]
        k = np.searchsorted(ts, t, side="right") - 1
        fresh = (k >= 0) & (t - ts[np.maximum(k, 0)] <= hold_s)
        out[fresh, j] = v[k[fresh]]
    return out


def rate_hz(t_src) -> float:
    """The readings' rate (Hz) from their median interval (0 for fewer than two)."""
    dt = np.diff(np.unique(np.asarray(t_src, float)))
    return float(1.0 / np.median(dt)) if len(dt) else 0.0


def rotor_meta(count, *, motors=None, table=None, frame=None, numbering="", sources=None, rates=None) -> dict:
    """``meta['rotors']``: the count, each column's motor in the source's numbering, the frame's
    arms (unit, body FRD) and spin directions (+1 clockwise seen from above) where the source
    states them, and where each channel comes from."""
    out = {"count": int(count)}
    if motors is not None:
        out["motors"] = [int(m) for m in motors]
    if numbering:
        out["numbering"] = numbering
    if table is not None:
        positions, spin = frame_geometry(table)
        out.update(frame=frame, positions=np.round(positions, 6).tolist(), spin=[int(s) for s in spin])
    out["sources"] = dict(sources or {})
    out["rates_hz"] = {k: round(v, 3) for k, v in (rates or {}).items()}
    return out


# -- PX4 -------------------------------------------------------------------------------------------------
PX4_ROTOR_TOPICS = ("actuator_motors", "actuator_outputs", "esc_status")


def px4_rotors(data, params, t) -> tuple[dict, dict | None]:
    """A ULog's rotor channels on the IMU's rows ``t`` (s) and their ``meta['rotors']``:
    ``actuator_motors`` (normalised thrust commands) or else ``actuator_outputs`` (PWM over the
    PWM range), and ``esc_status``'s rpm (ESC i taken as motor i). ``({}, None)`` without them."""
    notes: list[str] = []
    table, frame = px4_geometry(params, notes)
    n, out, sources, rates = len(table), {}, {}, {}
    if "actuator_motors" in data:
        am = data["actuator_motors"]
        cmd = np.column_stack([am[f"control[{i}]"] for i in range(n)]).astype(float)
        out["motor_command"] = on_rows(t, am["timestamp"] * 1e-6, np.clip(cmd, 0.0, 1.0))
        rates["motor_command"] = rate_hz(am["timestamp"] * 1e-6)
        sources["motor_command"] = "actuator_motors.control (PX4's normalised thrust command)"
    elif "actuator_outputs" in data:
        ao = data["actuator_outputs"]
        lo, hi = px4_pwm_range(params)
        pwm = np.column_stack([ao[f"output[{i}]"] for i in range(n)])
        out["motor_command"] = on_rows(t, ao["timestamp"] * 1e-6, pwm_share(pwm, lo, hi))
        rates["motor_command"] = rate_hz(ao["timestamp"] * 1e-6)
        sources["motor_command"] = f"actuator_outputs (PWM, µs) over PWM_MIN..PWM_MAX = {lo:g}..{hi:g}"
    if "esc_status" in data and f"esc[{n - 1}].esc_rpm" in data["esc_status"]:
        es = data["esc_status"]
        rpm = np.column_stack([es[f"esc[{i}].esc_rpm"] for i in range(n)]).astype(float)
        out["rotor_speed"] = on_rows(t, es["timestamp"] * 1e-6, np.abs(rpm) * RPM)
        rates["rotor_speed"] = rate_hz(es["timestamp"] * 1e-6)
        sources["rotor_speed"] = "esc_status.esc[i].esc_rpm (ESC i as motor i+1)"
    if not out:
        return {}, None
    numbering = "PX4's motor order (motor i+1 in column i)" + (f"; {notes[0]}" if notes else "")
    meta = rotor_meta(n, motors=range(1, n + 1), table=table, frame=frame, numbering=numbering, sources=sources,
                      rates=rates)  # fmt: skip
    return out, meta


# -- ArduPilot ------------------------------------------------------------------------------------------
def ardupilot_rotors(msgs, params, t) -> tuple[dict, dict | None]:
    """A DataFlash log's rotor channels on the IMU's rows ``t`` (s) and their ``meta['rotors']``:
    ``RCOU`` (rows ``TimeUS, C1..C14``) over the motors' PWM range, and ``ESC``'s rpm (rows
    ``TimeUS, Instance, RPM``; instance i taken as output channel i+1), each motor's by its
    ``SERVOn_FUNCTION``. ``({}, None)`` without them or with a frame quadest does not know."""
    key = (int(params.get("FRAME_CLASS", 1)), int(params.get("FRAME_TYPE", 1)))
    if key not in ARDUPILOT_FRAMES or not (msgs["RCOU"] or msgs["ESC"]):
        return {}, None
    frame, table = ARDUPILOT_FRAMES[key]
    notes: list[str] = []
    channels = motor_channels(params, len(table), notes)
    out, sources, rates = {}, {}, {}
    if msgs["RCOU"]:
        rcou = np.array(msgs["RCOU"], float)
        lo, hi = ardupilot_pwm_range(params)
        out["motor_command"] = on_rows(t, rcou[:, 0] * 1e-6, pwm_share(rcou[:, channels], lo, hi))
        sources["motor_command"] = f"RCOU (PWM, µs) over {lo:g}..{hi:g} µs"
        rates["motor_command"] = rate_hz(rcou[:, 0] * 1e-6)
    if msgs["ESC"]:
        esc = np.array(msgs["ESC"], float)
        rpm = np.full((len(esc), len(table)), np.nan)
        for j, ch in enumerate(channels):
            mine = esc[:, 1] == ch - 1
            rpm[mine, j] = np.abs(esc[mine, 2])
        if np.nan_to_num(rpm).any():  # ESCs without telemetry log 0 rpm throughout: no reading
            out["rotor_speed"] = on_rows(t, esc[:, 0] * 1e-6, rpm * RPM)
            sources["rotor_speed"] = "ESC.RPM (ESC telemetry; instance i as output channel i+1)"
            rates["rotor_speed"] = rate_hz(esc[np.isfinite(rpm[:, 0]), 0] * 1e-6)
    if not out:
        return {}, None
    numbering = "ArduPilot's motor numbers (motor i+1 in column i), outputs by SERVOn_FUNCTION"
    numbering += f"; {notes[0]}" if notes else ""
    meta = rotor_meta(len(table), motors=range(1, len(table) + 1), table=table, frame=frame, numbering=numbering,
                      sources=sources, rates=rates)  # fmt: skip
    return out, meta
