"""The rotor-failure detector's parameters (docs/detection.md): each with its unit, meaning,
source and bounds, packed by name for the compiled step (``p[PARAM.lost_threshold]``)."""

from __future__ import annotations

from dataclasses import dataclass

from quadest.records import Params, param, params_record


@dataclass(frozen=True)
class DetectorParams(Params):
    rotor_speeds: bool = param(
        True,
        "-",
        "the rotor speeds are measured (ESC telemetry); otherwise they follow from the commands "
        "through the detector's motor model",
    )
    gyro_noise: float = param(
        0.02,
        "rad/s",
        "gyroscope noise with vibration, per sample",
        "chosen: the presets' noise and vibration",
        "(0, 10]",
    )
    noise_window_s: float = param(
        0.2,
        "s",
        "the gyroscope's noise (with the rotors' vibration) is estimated over about this window from its "
        "second difference, and used when larger than gyro_noise (0: gyro_noise only)",
        "chosen: vibration changes with the rotor speeds within a second",
        "[0, 100]",
    )
    acc_noise: float = param(
        1.0, "m/s²", "accelerometer z noise with vibration, per sample", "chosen: the presets' vibration", "(0, 100]"
    )
    moment_noise: float = param(
        8.0,
        "rad/s²",
        "angular acceleration the model misses (inertia and thrust errors, aerodynamics)",
        "chosen: 10 % of the 80 rad/s² of aggressive flight",
        "(0, 1e4]",
    )
    model_error: float = param(
        0.15,
        "-",
        "relative error of the modelled roll and pitch moments (inertia, thrust coefficient)",
        "chosen: the ±10 % model errors the campaign draws, with margin",
        "[0, 10]",
    )
    yaw_model_error: float = param(
        0.3,
        "-",
        "relative error of the modelled yaw moment (drag torque coefficient, rotor drag)",
        "chosen: the yaw moment is the least known",
        "[0, 10]",
    )
    eta_walk: float = param(
        1.5,
        "1/√s",
        "random walk of a rotor's effectiveness",
        "chosen on training seeds 0-35 (3.0 before the disturbed flights)",
        "(0, 1e3]",
    )
    deficit_sd_ratio: float = param(
        2.0,
        "-",
        "a rotor's deficit counts only while the deviation of its effectiveness is below this "
        "many times the best-known rotor's (a rotor turning slowly shows little of its effectiveness)",
        "chosen",
        "[1, 100]",
    )
    weighted_others: bool = param(
        True,
        "-",
        "a rotor's deficit is against the others' effectiveness weighted by how well each is known (else "
        "their plain mean)",
        "measured: near-idle rotors' wandering effectiveness made the false alarms of saturated manoeuvres",
    )
    deficit_sigmas: float = param(
        0.0,
        "-",
        "a rotor's deficit counts only beyond this many of its standard deviations (0: always); "
        "for logs, whose rates and noise leave the effectiveness uncertain",
        "chosen: 0 in flight (the fast sensors make it certain), 3 for logs",
        "[0, 100]",
    )
    contact_margin: float = param(
        5.0,
        "m/s²",
        "a contact (the ground, an impact) is a specific force along −z beyond 1.3 times what the intact "
        "rotors make plus this; the tests hold during it, contact_hold_s after, and until the intact rotors "
        "make 0.9 g again (a vehicle standing on the ground: landed) (0: never)",
        "chosen: above the model's ±10 % thrust and mass error, the accelerometer's tone and a lost rotor's drop",
        "[0, 1000]",
    )
    contact_hold_s: float = param(
        0.5,
        "s",
        "the tests hold this long after a contact",
        "chosen: a touchdown's bounce settles within it",
        "[0, 100]",
    )
    cut_rotors: float = param(
        2.0,
        "-",
        "a thrust cut: the tests hold while at least this many rotors are commanded at their lowest speed, "
        "and cut_hold_s after (0: never)",
        "measured on training seeds: each alarm where a landing started (nominal 6000-6599) came within 50 ms "
        "of two or three rotors commanded to idle; the hold moved no alarm of a complete loss (0-399) "
        "(docs/detection.md)",
        "[0, 8]",
    )
    cut_hold_s: float = param(
        0.1,
        "s",
        "the tests hold this long after a thrust cut",
        "chosen on training seeds: of 0.05 and 0.1, the shorter without an alarm where a landing starts "
        "(at the edge for one flight: docs/detection.md)",
        "[0, 100]",
    )
    air_drag: bool = param(
        True,
        "-",
        "the yaw moment of each rotor's drag as the vehicle moves through the air, read from the "
        "accelerometer's x and y (their specific force is the rotors' and the body's drag: docs/detection.md)",
        "measured on training seeds, beside relative_deficit: alarms 2 / 1 against 3 / 5 in 12 h (rotor speeds / "
        "commands), 288 against 287 of 300 losses up, p99 delay 56 against 64 ms; alone, 283 up (docs/detection.md)",
    )
    relative_deficit: bool = param(
        True,
        "-",
        "a rotor's deficit is relative to the others' effectiveness, (η̄ − η_i) / max(η̄, 0.5), so that an error "
        "common to every rotor (thrust coefficient, mass, the vehicle's own inflow), which scales every η alike, "
        "leaves a lost rotor's deficit at 1; else the plain difference η̄ − η_i, which that error scales",
        "measured on training seeds: alone, losses found sooner (p90 41 against 61 ms) and more alarms with the "
        "commands (5 against 2 in 12 h); with air_drag, fewer alarms and sooner (docs/detection.md)",
    )
    glr: bool = param(
        True,
        "-",
        "a fast test beside the 'lost' CUSUM: over the last samples, the gyroscope's change and the "
        "accelerometer's z against the model with the effectiveness before them, a generalised likelihood "
        "ratio for each rotor lost when they began (docs/detection.md, The fast test)",
        "measured on training seeds: losses found in 17 against 24 ms (median), 292 against 288 of 300 up, "
        "no alarm added in 12 h (docs/detection.md)",
    )
    glr_window_s: float = param(
        0.02, "s", "the fast test's longest window (each shorter one down to 3 samples is tried too; at most "
        "31 samples, the ring's: 15.5 ms at 2 kHz)",
        "chosen: a loss's rate change passes the model's unmodelled acceleration within 10-20 ms", "(0, 0.06]",
    )  # fmt: skip
    glr_threshold: float = param(
        150.0,
        "-",
        "the fast test's threshold on twice its log-likelihood ratio",
        "chosen on training seeds: about 1.5 times the largest in 12 h of nominal flight in either mode (103; "
        "docs/detection.md)",
        "(0, 1e12]",
    )
    glr_min_loss: float = param(
        0.7, "-", "the share of the rotor's contribution the fast test must find gone to name it",
        "chosen: above the 'lost' test's drift (0.6)", "(0, 10]",
    )  # fmt: skip
    glr_margin: float = param(
        4.0,
        "-",
        "the fast test names a rotor only when its ratio is this many times the next rotor's",
        "chosen",
        "[1, 1e12]",
    )
    moment_scale_s: float = param(
        10.0,
        "s",
        "memory of the rotors' moment per axis learnt in flight against the detector's model (inertia, mass, "
        "thrust coefficient off), by least squares on the band-passed rate change (0: the model as given)",
        "chosen on training seeds: alarms in 12 h of nominal flight 1 / 0 (rotor speeds / commands) against 2 / 1 "
        "without, the losses' delays alike (docs/detection.md, The moment learnt in flight)",
        "[0, 1e4]",
    )
    moment_scale_prior: float = param(
        5.0,
        "rad/s²",
        "the learnt moment stays near the model's until the modelled angular acceleration, band-passed, passes "
        "about this RMS over the memory (a hover's corrections of its own disturbances would bias it low)",
        "chosen on five training flights: 2 biased the hovers' scale 3-9 % lower",
        "(0, 1e4]",
    )
    lever_arm: bool = param(
        True,
        "-",
        "remove from the accelerometer's reading what its place off the centre of mass adds (the IMU's position "
        "given to the detector; off: the reading taken as the centre of mass's)",
        "measured: docs/detection.md, The accelerometer's place",
    )
    lost_drift: float = param(0.6, "-", "deficit the 'lost' test ignores (ν)", "chosen: above a 50 % loss", "(0, 1]")
    lost_threshold: float = param(
        0.004,
        "s",
        "the 'lost' test's threshold (h, deficit-seconds)",
        "chosen on training seeds 0-399 and nominal 0-119 (the smallest without an alarm in either mode, with the "
        "thrust-cut hold; 0.008 before it; docs/detection.md)",
        "(0, 10]",
    )
    speed_test: bool = param(
        True,
        "-",
        "with the rotor speeds measured and the commands known, a rotor whose speed falls below what any working "
        "motor within the model's errors (speed_tau_ratio, speed_top_sag) reaches from its commands is lost: a "
        "stopped motor or a desync, which still makes the thrust its speed gives (docs/detection.md, The motor's "
        "speed)",
        "measured on the campaign's losses: a stopped motor was found in 1 of 120 without it (docs/detection.md)",
    )
    speed_tau_ratio: float = param(
        2.0,
        "-",
        "the speed test's motor time constant may be this many times the model's, or this many times less",
        "chosen: the motor's time constant × 2 and × 0.5 the detector must stand (docs/detection.md)",
        "[1, 100]",
    )
    speed_top_sag: float = param(
        0.15,
        "-",
        "the speed test's top and lowest speeds may be this share below the model's (a sagging battery)",
        "chosen: a top speed 15 % low, which the detector must stand (docs/detection.md)",
        "[0, 0.9]",
    )
    speed_noise: float = param(
        0.01,
        "-",
        "relative noise of a rotor speed reading; a reading lifts the speed test's floor to itself less three of it",
        "chosen: eRPM telemetry resolves about 1 % at hover speed (the loop's speed_noise)",
        "[0, 0.3]",
    )
    speed_drift: float = param(
        0.1,
        "-",
        "the speed test ignores a shortfall below its floor of this share of the model's top speed (ν)",
        "chosen: ten times a reading's noise at top speed; 0.13 is the floor's largest rise over a reading held 10 ms "
        "(docs/detection.md, The motor's speed)",
        "(0, 1]",
    )
    speed_threshold: float = param(
        0.002,
        "s",
        "the speed test's threshold (h, shares of the top speed times seconds)",
        "chosen on synthetic motors: 1.7 times the largest sum (0.00115) of working motors whose time constant is "
        "0.5-2 times the model's and top speed 15 % low, read at 100 Hz with 1 % noise, under full-range command "
        "steps; a motor stopped at hover speed passes it in 25 ms (docs/detection.md)",
        "(0, 10]",
    )
    damaged_drift: float = param(
        0.15,
        "-",
        "deficit the 'damaged' test ignores (ν)",
        "chosen: half the smallest loss looked for (30 %)",
        "(0, 1]",
    )
    damaged_threshold: float = param(
        0.02, "s", "the 'damaged' test's threshold (h)", "chosen: tuned on training seeds", "(0, 100]"
    )


PARAM = Record = params_record(DetectorParams)
