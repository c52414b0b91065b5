"""``robust``'s parameters, the layout of its state and its coefficients (docs/estimators.md,
robust: the equations R1-R8 and how each default was chosen)."""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

from quadest.conventions import GRAVITY
from quadest.filters.base import Params, coefficient_offsets, params_record
from quadest.filters.common import BASE, layout
from quadest.records import param

DEG = math.pi / 180.0
VQF = "Laidig & Seel 2023 (VQF), the published default"

STATE = layout(
    ("qg", 4),  # q_Ib: gyro strapdown, body -> almost-inertial frame I
    ("qi", 4),  # q_EI: inclination correction, I -> E
    ("delta", 1),  # heading offset δ about down, E -> n (rad)
    ("lp", 12),  # Butterworth state of f_I: (s1, s2) per axis and section (eq R1c)
    ("lpy", 3),  # the low-pass output (f_I filtered)
    ("mean_n", 1),  # samples in the initial averaging (until τ_acc has passed)
    ("coef_dt", 1),  # Δt the cached coefficients were computed for
    ("clock", 4),  # eq R9: intervals counted, their running mean (s), a one-sided run's count (signed) and time (s)
    ("coef", 8),  # b0, a1, a2, k_acc, k_rest, k_mag_lp, k_init, spare
    ("bias", 3),  # gyro bias, body, rad/s
    ("Pb", 9),  # its covariance, row-major
    ("hlp", 36),  # eq R3d: Butterworth state of R(q_Eb)'s rows (north, east, down), 3 entries each
    ("hrow", 9),  # their low-pass output
    ("wlp", 1),  # eq R1c: the rate's norm low-passed (first order, τ_acc), rad/s
    ("hblp", 8),  # Butterworth state of R(q_Eb) b, north and east
    ("rest_g", 3),
    ("rest_a", 3),  # low-passed gyro and accelerometer for rest detection
    ("rest_t", 1),  # time at rest so far, s
    ("mag_n", 1),  # magnetometer updates so far (initial averaging of the heading)
    ("moved", 1),  # 1: the initial averaging ended at an acceleration (eq R8); -1: started turning
    ("ys", 3),  # f_I low-passed over init_tau during the initial averaging
    ("fprev", 3),  # the previous f_I (its noise from successive differences)
    ("yok", 3),  # the mean when the recent specific force was last within half the threshold
    ("fvar", 1),  # mean square of f_I's noise, summed over the axes (m²/s⁴)
    ("mag_dt", 1),  # time since the last magnetometer sample, s
    ("ref", 2),  # reference field norm (magnetometer's unit) and dip (rad); norm 0: not set
    ("cur", 2),  # low-passed current norm and dip
    ("cand", 2),  # candidate new reference norm and dip
    ("cand_t", 1),  # time the candidate has been consistent, s
    ("ref_conf", 1),  # 1 once a reference has been confirmed (the first acceptance is faster)
    ("undist_t", 1),  # time undisturbed so far, s
    ("reject_t", 1),  # accumulated rejection time, s
    ("disturbed", 1),
    ("mprev", 3),  # previous magnetometer sample (body), NaN: none
    ("gsum", 3),  # the gyro integrated since the last magnetometer sample (rad)
    ("gclip", 3),  # 1 if the axis clipped since the last magnetometer sample
    ("rate", 3),  # eq R4: a clipped axis's rate (rad/s)
    ("accel", 3),  # eq R4d: its angular acceleration (rad/s²)
    ("Pc", 36),  # eq R4f: the joint covariance of (ω_x, ω_y, ω_z, α_x, α_y, α_z), row-major
    ("fresh", 3),  # 1 while an axis's (ω, α) is its reading's, uncorrelated with the others'
    ("sd2", 1),  # eq R4f: the variance of a component of the field's change rate (learnt while unclipped)
    ("sdt", 1),  # time it has been learnt, s
    ("work", 45),  # eq R4f's workspace: P Hᵀ, the gain, S
    ("ascale", 3),  # the slope at the clip, decaying with the acceleration (rad/s²)
    ("wmean", 3),  # the last in-range interval's mean reading (rad/s)
    ("wmid", 3),  # time since its midpoint, s (0: none yet)
    ("Vn", 3),  # variance of the numerator of eq R4 (the field's noise), learnt while unclipped
    ("Vt", 3),  # time it has been learnt, s
    ("peak", 3),
    ("trough", 3),  # largest and smallest gyro reading seen per axis
    ("peak_n", 3),
    ("trough_n", 3),  # samples since each was set
    ("level", 3),  # the reading a flat top began at
    ("flat", 3),
    ("gflat", 3),  # a flat top not yet confirmed a clip: now, since the last magnetometer sample
    ("ev_s", 3),
    ("ev_w", 3),  # the field's evidence on it (eq R4c): Σ excess/variance, Σ 1/variance
    ("lim_pos", 3),
    ("lim_neg", 3),  # confirmed limits per axis and sign (0: none)
    ("rep", 3),  # exact repeats of the reading on the flat top so far
    ("gprev", 3),  # previous raw gyro sample
    ("clipped", 3),  # 1 while an axis is clipped
    ("hold", 3),  # the rate held on a clipped axis
    ("debt", 3),  # rotation owed on a clipped axis (rad, ≤ 0): the limit's excess over the field's rate
    ("spin", 1),  # low-passed rate about down (signed), rad/s
    ("Pt", 1),
    ("Ph", 1),  # tilt and heading error variances (rad²)
    ("Ra", 1),
    ("Rm", 1),  # low-passed squared accelerometer / heading innovations (rad²)
    start=BASE,
)

UNKNOWN_HEADING_VAR = math.pi**2 / 3.0  # variance of a heading uniform on the circle


@dataclass(frozen=True)
class RobustParams(Params):
    use_mag: bool = param(True, "-", "use the magnetometer when samples are present", "quadest: 9-axis when present")
    tau_acc: float = param(
        4.0,
        "s",
        "time constant of the specific force's low-pass in the almost-inertial frame",
        "chosen: the 2nd-order low-pass (cut-off √2/(2π τ)) attenuates a vehicle's 2 m/s² manoeuvre at "
        "0.2 Hz to 1° of tilt; on BROAD's split 3-5 s are within 0.04° (VQF: 3 s)",
        bounds="(0, 1e3]",
    )
    lp_rate: float = param(
        0.0,
        "rad/s",
        "eq R1c: the specific force's low-pass (and the rows of eq R3d) is the 2nd-order Butterworth "
        "plus a share 1/(1 + (lp‖ω‖/lp_rate)²) of what a second section in series changes (a 4th "
        "order: far less of a sustained manoeuvre's acceleration, twice the delay, which a rotation's "
        "scale-factor drift turns into tilt); 0: the 2nd order alone",
        "chosen: off (it costs BROAD's undisturbed trials and the simulator's yaw); for 6-axis "
        "multirotor flights 0.5 rad/s, chosen on half of the shared flights (docs/estimators.md)",
        bounds="[0, 1e3]",
    )
    tau_mag: float = param(
        15.0,
        "s",
        "time constant of the heading correction",
        "BROAD split (docs/estimators.md): the halves chose 15 and 25 s; the shorter one (VQF: 9 s)",
        bounds="(0, 1e4]",
    )
    spin_min: float = param(
        3.0,
        "rad/s",
        "sustained rate about the vertical above which the vehicle is spinning",
        "chosen: a hand rarely keeps turning one way at 3 rad/s for seconds; a quadcopter "
        "spinning after a rotor loss turns at 10-20 rad/s",
        bounds="[0, 1e3]",
    )
    spin_rate: float = param(
        0.6,
        "rad/s",
        "each this much of sustained rate above spin_min divides the heading's time constant once more",
        "chosen: at 15 rad/s the time constant is 0.7 s, which follows "
        "a 0.5 % scale-factor drift of the spin (4 °/s) within 3°",
        bounds="(0, 1e3]",
    )
    spin_tau: float = param(
        2.0,
        "s",
        "time constant of the low-pass of the (signed) rate about the vertical",
        "chosen: a spin lasts seconds; a hand's back-and-forth turns cancel within two",
        bounds="(0, 1e3]",
    )
    bias_from_heading: bool = param(
        True,
        "-",
        "the heading correction's rate measures the vertical bias",
        "quadest's addition (VQF: inclination only)",
    )
    gyro_noise: float = param(
        0.005,
        "rad/√s",
        "gyroscope noise density (for the reported covariance)",
        "chosen: a consumer MEMS gyro (0.3 °/s/√Hz)",
        bounds="[0, 1]",
    )
    acc_corr_s: float = param(
        0.02,
        "s",
        "correlation time of unmodelled accelerations (for the reported covariance)",
        "chosen on simulator seeds 11-15 (docs/estimators.md)",
        bounds="[0, 100]",
    )
    bias_init: float = param(
        0.5 * DEG, "rad/s", "initial gyro bias std", VQF + " (σ_bias,init 0.5 °/s)", bounds="[0, 1]"
    )
    bias_drift: float = param(
        0.1 * DEG / 10.0,
        "rad/s/√s",
        "gyro bias random walk",
        "from VQF's σ_motion 0.1 °/s over its 100 s forgetting time",
        bounds="[0, 1]",
    )
    bias_motion_std: float = param(
        0.2 * DEG,
        "rad/s",
        "noise of the bias measurement from the inclination correction, per τ_acc",
        "BROAD split (docs/estimators.md): the halves chose "
        "0.2 and 0.8 °/s; the smaller one (the simulator's flights need the bias in motion)",
        bounds="(0, 1]",
    )
    bias_gain: float = param(
        0.25,
        "-",
        "largest gain of the bias loop closed by the inclination correction, in units "
        "of Δt/τ_acc (0.25: critically damped; more rings)",
        "quadest: critical damping (eq R3b)",
        bounds="(0, 1]",
    )
    bias_rows_lp: bool = param(
        True,
        "-",
        "the bias in motion measured against the low-passed rows of the attitude (eq R3d), as the "
        "correction comes from the low-passed force",
        "VQF's in-motion bias estimate (Laidig & Seel 2023); quadest before: the rows of the moment",
    )
    bias_heading_std: float = param(
        0.2 * DEG,
        "rad/s",
        "noise of the bias measurement from the heading correction, per τ_ψ",
        "chosen: as bias_motion_std",
        bounds="(0, 1]",
    )
    bias_heading_gain: float = param(
        1.0,
        "-",
        "largest gain of the bias loop closed by the heading correction, in "
        "units of the heading's gain k (0.25: critically damped; 1: damping 0.5)",
        "chosen on simulator seeds 1-5 (docs/estimators.md)",
        bounds="(0, 4]",
    )
    bias_rest_std: float = param(
        0.03 * DEG, "rad/s", "noise of the bias measurement at rest", VQF + " (σ_rest 0.03 °/s)", bounds="(0, 1]"
    )
    bias_clip: float = param(
        2.0 * DEG, "rad/s", "largest gyro bias estimated at rest", VQF + " (2 °/s)", bounds="(0, 1]"
    )
    scale_max: float = param(
        0.005,
        "-",
        "largest gyro scale-factor error: in motion the bias (which then also absorbs "
        "the scale error times the rate) may reach bias_clip + scale_max |ω|",
        "chosen: consumer MEMS gyros are specified to ±0.5 % or better (the bebop2 preset: σ 0.3 %)",
        bounds="[0, 1]",
    )
    rest_tau: float = param(0.5, "s", "low-pass time constant of the rest detection", VQF, bounds="(0, 100]")
    rest_gyr: float = param(
        2.0 * DEG, "rad/s", "rest: largest gyro deviation from its low-pass", VQF + " (2 °/s)", bounds="(0, 10]"
    )
    rest_acc: float = param(
        0.5, "m/s²", "rest: largest accelerometer deviation from its low-pass", VQF, bounds="(0, 100]"
    )
    rest_time: float = param(1.5, "s", "rest: how long both must hold", VQF, bounds="[0, 1e3]")
    mag_lp_tau: float = param(0.05, "s", "low-pass time constant of the field's norm and dip", VQF, bounds="(0, 100]")
    mag_norm_th: float = param(
        0.1, "-", "disturbed: relative deviation of the norm from the reference", VQF, bounds="(0, 10]"
    )
    mag_dip_th: float = param(
        10.0 * DEG, "rad", "disturbed: deviation of the dip from the reference", VQF + " (10°)", bounds="(0, 3.2]"
    )
    mag_ref_tau: float = param(
        20.0, "s", "time constant of the reference's update while undisturbed", VQF, bounds="(0, 1e6]"
    )
    mag_new_time: float = param(
        20.0, "s", "a new consistent field becomes the reference after this long", VQF, bounds="[0, 1e6]"
    )
    mag_new_first: float = param(5.0, "s", "the same for the first reference", VQF, bounds="[0, 1e6]")
    mag_min_undist: float = param(0.5, "s", "undisturbed after this long within the thresholds", VQF, bounds="[0, 1e3]")
    mag_max_reject: float = param(60.0, "s", "longest rejection of a disturbed field", VQF, bounds="[0, 1e6]")
    mag_reject_factor: float = param(
        2.0,
        "-",
        "after the longest rejection: the gain divided by this; rejection time "
        "is paid back this much faster while undisturbed",
        VQF,
        bounds="[1, 1e3]",
    )
    clip_learn_tau: float = param(
        1.0,
        "s",
        "time constant over which the field's noise is learnt for a clipped axis's rate (eqs R4b, R4f)",
        "chosen: many magnetometer samples, yet recent",
        bounds="(0, 1e4]",
    )
    clip_heading_tau: float = param(
        0.25,
        "s",
        "longest time constant of the heading correction while a vertical axis "
        "is clipped (divided by the clipped axes' squared share about down)",
        "chosen: a 1 % rate error at 15 rad/s drifts 9 °/s, held to about 2° by 0.25 s (docs/estimators.md)",
        bounds="(0, 1e4]",
    )
    gyro_range: float = param(
        0.0,
        "rad/s",
        "the gyroscope's range (0: detect clipping from a flat top)",
        "quadest: unknown unless given",
        bounds="[0, 1e3]",
    )
    clip_flat: float = param(
        0.005,
        "-",
        "relative spread of a clipped axis's readings (flat top and known range)",
        "chosen: RepoIMU's calibrated readings wander by 0.3 % on a clipped axis",
        bounds="[0, 0.1]",
    )
    clip_plateau: float = param(
        1.0,
        "samples",
        "a flat top's extreme must have stood this long before a reading at it counts as clipped",
        "chosen: a ramp sets a new extreme at every sample; a clipped axis repeats its limit",
        bounds="[0, 1e3]",
    )
    clip_repeat: float = param(
        20.0,
        "samples",
        "exact repeats of a flat top's reading that confirm it a clip",
        "chosen: a quantised reading (BROAD's 0.06 °/s steps at 286 Hz) holds a few samples at "
        "a smooth peak, a clipped one as long as the clip",
        bounds="[1, 1e6]",
    )
    clip_confirm: float = param(
        3.0,
        "-",
        "standard errors by which the field's rate must exceed a flat top's readings to confirm it a clip (eq R4c)",
        "chosen: a one-sided 3σ test; a steady spin at its fastest is no clip",
        bounds="(0, 1e3]",
    )
    clip_rate_q: float = param(
        2.0,
        "rad²/s³",
        "random-walk intensity of a clipped axis's rate (eq R4d)",
        "chosen on the flown rotor loss, seeds 1-5, with the clipped axes corrected together (eq R4f; "
        "docs/estimators.md): 0.25-2 within 0.5° of each other, 2 the largest (RepoIMU's clipping "
        "trial costs more below it); 16 costs the spin clipped throughout, whose field's rate is noisy",
        bounds="(0, 1e6]",
    )
    clip_accel_tau: float = param(
        0.4,
        "s",
        "time constant over which a clipped axis's angular acceleration decays, and the noise on it (eq R4d)",
        "chosen on the flown rotor loss, seeds 1-5, the axes corrected one by one (0.3-0.6 s within "
        "noise), and again with eq R4f (0.2 costs the spin clipped throughout; docs/estimators.md): "
        "its rate climbs beyond the range for about 0.3 s and falls back",
        bounds="(0, 1e3]",
    )
    clip_accel_change: float = param(
        6.0,
        "-",
        "how far a clipped axis's angular acceleration may change within clip_accel_tau, in units "
        "of the slope at which it clipped (eq R4d)",
        "chosen on the flown rotor loss, seeds 1-5, the axes corrected one by one (√32-√64 within "
        "noise), and again with eq R4f (3, 4, 8 and 10 cost; docs/estimators.md): a tumble's "
        "acceleration reverses at its peak",
        bounds="[0, 1e3]",
    )
    clip_min_rate: float = param(
        4.3,
        "rad/s",
        "smallest rate a flat top can be clipping at",
        "chosen: the smallest common MEMS range, ±250 °/s",
        bounds="(0, 1e3]",
    )
    lever_x: float = param(
        0.0, "m", "IMU position from the centre of gravity, forward", "chosen: unknown, none", bounds="[-10, 10]"
    )
    lever_y: float = param(
        0.0, "m", "IMU position from the centre of gravity, right", "chosen: unknown, none", bounds="[-10, 10]"
    )
    lever_z: float = param(
        0.0, "m", "IMU position from the centre of gravity, down", "chosen: unknown, none", bounds="[-10, 10]"
    )
    mag_latency_s: float = param(0.0, "s", "age of a magnetometer sample", "chosen: unknown, none", bounds="[0, 1]")
    init_tau: float = param(
        0.05,
        "s",
        "the initial averaging: time constant of the recent specific force compared with its mean (eq R8)",
        "chosen: a maneuver's onset within a few tens of ms, the noise averaged over 25 samples at 500 Hz",
        bounds="(0, 100]",
    )
    init_acc: float = param(
        0.5,
        "m/s²",
        "the initial averaging ends once the recent specific force leaves its mean by this much (eq R8)",
        "chosen: VQF's rest threshold (rest_acc)",
        bounds="[0, 1e6]",
    )
    gravity: float = param(GRAVITY, "m/s²", "gravity", "standard gravity", bounds="(0, 100]")


PARAM = Record = params_record(RobustParams)
Coefficients = namedtuple("Coefficients", ["has_lever", "sg2"])
COEF = coefficient_offsets(Coefficients)


def coefficients(p: RobustParams) -> Coefficients:
    """Whether a lever arm is given; the gyro's noise variance density."""
    return Coefficients(
        has_lever=float(p.lever_x != 0.0 or p.lever_y != 0.0 or p.lever_z != 0.0), sg2=p.gyro_noise * p.gyro_noise
    )
