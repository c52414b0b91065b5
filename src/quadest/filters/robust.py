"""quadest's own attitude estimator, ``robust``: one filter and one set of defaults for every
regime a quadcopter meets (docs/estimators.md, robust).

Its structure follows the ideas that make VQF accurate on real recordings (Laidig & Seel,
"VQF: Highly accurate IMU orientation estimation with bias estimation and magnetic disturbance
rejection", Information Fusion 91, 2023); the code is quadest's own, written in quadest's
conventions (NED / FRD, ``q_nb``):

1. **Strapdown in an almost-inertial frame I.** ``q_Ib ← q_Ib ⊗ Exp((ω − b) Δt)``.
2. **Inclination from the specific force low-pass filtered in I.** ``f_I = R(q_Ib) f`` is
   filtered by a second-order Butterworth low-pass (cut-off ``√2 / (2π τ_acc)``); a brief
   acceleration integrates to a velocity change and cancels, while the rotation itself is
   carried by the gyroscope and never slowed. The inclination correction ``q_EI`` is updated
   every sample to the rotation that takes the filtered direction ``u = −R(q_EI) lp(f_I) / ‖·‖``
   onto the down axis: ``q_c = [√((1 + u_z)/2), u_y / (2 w), −u_x / (2 w), 0]`` (eq R1, the
   shortest rotation from ``u`` to ``e_z``), ``q_EI ← q_c ⊗ q_EI``.
3. **Heading as a separate offset** about the down axis, ``q_nb = Rz(δ) ⊗ q_EI ⊗ q_Ib``: the
   magnetometer in E, ``m_E = R(q_EI ⊗ q_Ib) m``, gives ``δ_m = −atan2(m_E,y, m_E,x)`` (eq R2),
   and ``δ ← δ + k wrap(δ_m − δ)`` with ``k = max(1 − exp(−Δt_m / τ_ψ), 1 / n)`` (the first n
   samples are averaged, so the start converges at once, until eq R8 ends the averaging:
   item 11). The same filter gives the 6-axis
   attitude (δ held) and the 9-axis one; the magnetometer never tilts the estimate.
4. **Gyro bias** by a small Kalman filter on ``b`` (body, 3 states, covariance ``P_b``):
   - at rest (every sample of gyro and accelerometer within ``rest_gyr`` / ``rest_acc`` of
     their low-pass for ``rest_time``): the low-passed gyro measures ``b`` directly (noise
     ``bias_rest_std``). Sensors as noisy as the simulator's bebop2 preset at 500 Hz (gyro
     0.01 rad/s, accelerometer 0.25 m/s² a sample) exceed the thresholds every few hundred
     samples and rest is not seen; a mean-square test would see it, but takes a slow
     translation for rest;
   - in motion: the inclination correction's rate ``y = θ_c / Δt`` (E frame, horizontal) is
     the drift a bias error causes, ``y ≈ −H (b_true − b)`` with ``H`` the horizontal rows of
     ``R(q_EI ⊗ q_Ib)`` (eq R3); successive corrections come from one low-pass and are
     correlated over ``τ_acc``, so a sample carries ``Δt / τ_acc`` of one independent
     measurement: ``r = bias_motion_std² τ_acc / Δt``. The correction rate is the proportional
     term of a loop whose integral term this update is (``k_i = K k_p / Δt`` with
     ``k_p = 1/τ``): the gain K along the measurement row is capped at ``Δt / (4 τ)``, which keeps
     that loop at most critically damped (``k_i ≤ k_p² / 4``, eq R3b); an initial bias variance
     far above the measurement's would otherwise make the bias overshoot and ring (seen on the
     simulator: ±1 °/s swings in the first seconds). The update is made only while
     ``scale_max |ω| ≤ bias_motion_std`` (eq R3c: 0.7 rad/s by default): faster, the gyro's
     scale-factor error alone exceeds the bias to be resolved, and a manoeuvre's accelerations,
     turning with the vehicle, are rectified into a false bias (Blackbird's yaw-forward clover:
     roll 3.9° → 3.5°). The heading correction's rate gives the
     vertical row when the magnetometer is trusted (quadest's addition; during a spin it
     absorbs the gyro's scale-factor drift about the spin axis). Its gain along the row is capped
     at ``bias_heading_gain · k`` (k the heading's gain): with the default 1 that loop has damping
     0.5 and natural frequency 1/τ_ψ (``e'' + e'/τ + g e/τ² = 0``: ζ = 1/(2√g)), twice as fast as
     the critically damped 0.25, which left a 0.2 °/s vertical bias half learnt after a minute
     and the heading lagging by the rest times τ_ψ. Without it the vertical axis is
     weakly observable: its variance is capped at the initial one.
5. **Magnetic disturbance** detected from the field's norm and dip (relative to a reference
   learnt while undisturbed) and rejected for up to ``mag_max_reject`` s; a new field that stays
   consistent for ``mag_new_time`` s (``mag_new_first`` for the first) becomes the reference.

What VQF lacks and a quadcopter needs (quadest's additions):

6. **Gyro clipping.** An axis is clipped when it reads within ``clip_flat`` of ``gyro_range``;
   with ``gyro_range = 0`` a flat top (beyond ``clip_min_rate``, at the extreme of its sign,
   :func:`_detect_clip`) becomes a clip once its limit is confirmed, by a reading repeated
   exactly or by the field showing the axis turning faster than it reads (eq R4c): a steady
   spin at its fastest is a flat top too. The signs' limits are tracked apart (calibrated
   readings clip at +416.6 and −421.6 °/s on RepoIMU's TStick trial 5). While clipped, the
   axis's rate comes from the magnetometer's rotation in the body, ``ṁ = −ω × m`` solved for
   ``ω_i`` in least squares per magnetometer interval (eq R4, :func:`_mag_rate_terms`) and
   filtered by a scalar Kalman filter with a random-walk rate (``clip_rate_q``) whose
   measurement noise is learnt while the axis reads within range (eq R4b,
   :func:`_clip_rate_update`): a clean field is followed within a sample or two (a swinging
   stick), a noisy one averaged over a fraction of a second (a spin's horizontal field). The
   rate is never below the limit; what the limit adds beyond the estimate is owed and paid back
   once the estimate exceeds it (the bound would otherwise rectify the estimate's noise into a
   drift). Without a magnetometer the limit is held (the true rate is at least that). No bias
   is removed from a clipped axis, and while one is clipped the heading follows the
   magnetometer within ``clip_heading_tau`` divided by the clipped axes' squared share about
   down (a horizontal axis's rate error tilts the attitude; trusting the field's heading then
   would carry the tilt's error into the heading).
7. **Lever arm.** ``f ← f − ω × (ω × r)`` with ``r`` the IMU's position from the centre of
   gravity (``lever_x/y/z``); the ``ω̇ × r`` term is left to the low-pass (it integrates to
   ``Δω × r``, bounded).
8. **Spin-aware heading.** A gyro's scale-factor error ``s`` turns a net rotation about the
   vertical at ``ω_D`` into a heading drift ``s ω_D`` (a back-and-forth turn drifts and drifts
   back), which a heading filter of time constant τ follows with a lag of about ``s ω_D τ``. So
   the magnetometer is trusted more while the vehicle spins:
   ``τ_ψ,eff = τ_ψ / (1 + max(0, |lp(ω_D)| − spin_min) / spin_rate)`` (eq R7), ``lp`` a
   first-order low-pass (``spin_tau``) of the signed rate about down, so that only a sustained
   spin counts (a hand's turns cancel). On BROAD a smooth rule without the threshold
   (``τ ∝ (d₀ / (d₀ + s |lp(ω_D)|))^(2/3)``, the optimum for a drift d against correlated field
   errors) cost 0.1° total, the unfiltered rate 0.2°: hands do turn one way for seconds. The
   AFCKF's fuzzy gain also trusts the magnetometer more the faster the vehicle turns
   (eqs 46-51).
9. **Magnetometer latency.** A sample ``τ_m`` old is rotated forward by the gyro,
   ``m ← Exp(−ω τ_m) m`` (eq R5, from ``m_b(t) = R(t)ᵀ m_n`` and ``R(t) = R(t − τ_m) Exp(ω τ_m)``).
10. **Reported covariance** of the attitude error in the navigation frame, diagonal:
    tilt ``P_θ`` about north and east, heading ``P_ψ`` about down (eq R6):
    ``P_θ ← (1 − k)² (P_θ + (σ_g² + τ_acc tr(P_b) / 3) Δt) + k² R_a (1 + 2 τ_c / Δt)`` with
    ``k = 1 − exp(−Δt / τ_acc)``, ``R_a`` the low-passed squared angle between the raw specific
    force and the vertical (the accelerometer's direction noise, adaptive) and ``τ_c`` the
    correlation time of unmodelled accelerations (``acc_corr_s``). The heading's the same way
    with the magnetometer's squared heading innovation for ``R_a``, no correlation term,
    ``τ_ψ,eff`` for ``τ_acc`` and the variance of the heading's drift rate for ``tr(P_b) / 3``:
    the vertical bias's ``h P_b hᵀ``, plus ``(scale_max |lp(ω_D)|)²`` for the spin's
    scale-factor drift, plus a clipped axis's rate variance (eq R4b) seen about down. Without a
    magnetometer ``P_ψ`` is ``π²/3`` (heading unknown, uniform).
11. **The initial averaging ends at a sustained acceleration** (eq R8). Items 2 and 3 average
    their first samples (a running mean for ``τ_acc``, ``1 / n`` for ``τ_ψ``), which assumes
    no acceleration lasts. A vehicle that starts still and then accelerates for seconds (a
    circle flown from hover: 9° of centripetal tilt within 0.25 s) would put that
    acceleration into the mean, and its tilt error through the field's dip into the heading
    (67°: 12° of heading). So while averaging, the specific force's mean over the last
    ``init_tau``, ``s`` (a running mean for the first ``init_tau``), is compared with the mean
    so far, ``ȳ``: once ``‖s − ȳ‖² > max(init_acc², 16.3 σ² (k/(2 − k) + 1/n))`` (σ² the
    per-sample noise of ``f_I`` from successive differences, ``var(f_k − f_k−1) = 2 σ²``;
    ``k/(2 − k)`` and ``1/n`` the variances of the two means in units of σ²; 16.3 the 99.9 %
    point of χ² with 3 degrees of freedom), both averagings end: the inclination's low-pass
    starts at the mean as it was when ``‖s − ȳ‖`` was last within half the threshold (before
    the acceleration began) and the heading continues with ``1 − exp(−Δt_m / τ_ψ)``. Only a
    start that is still has such a reference: if the first gyro sample exceeds the rest
    detection's bound (``√3 (bias_clip + rest_gyr)``, 6.9 °/s) the averaging runs its course
    (a log that begins in flight: Blackbird's val segment, 27° off at its first sample,
    converges within 2 s by the averaging and within 8 s without it).
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import carray, njit
from quadest.conventions import GRAVITY
from quadest.filters.base import Estimator, P, Params, coefficient_offsets, params_record
from quadest.filters.common import BASE, INIT, Q_OUT, admit, layout, publish, wrap_angle
from quadest.rotation.kernels import FASTMATH, normalize_s, rotate_s

DEG = math.pi / 180.0
VQF = "Laidig & Seel 2023 (VQF), the published default"

S = layout(
    ("qg", 4),  # q_Ib: gyro strapdown, body -> almost-inertial frame I
    ("qi", 4),  # q_EI: inclination correction, I -> E
    ("delta", 1),  # heading offset δ about down, E -> n (rad)
    ("lp", 6),  # Butterworth state of f_I: (s1, s2) per axis
    ("lpy", 3),  # the low-pass output (f_I filtered)
    ("mean_n", 1),  # samples in the initial averaging (until τ_acc has passed)
    ("coef_dt", 1),  # Δt the cached coefficients were computed for
    ("coef", 8),  # b0, a1, a2, k_acc, k_rest, k_mag_lp, k_init, spare
    ("bias", 3),  # gyro bias, body, rad/s
    ("Pb", 9),  # its covariance, row-major
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
    ("rate", 3),
    ("Pw", 3),  # eq R4: a clipped axis's rate (rad/s) and its variance
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
    use_mag: bool = P(True, "-", "use the magnetometer when samples are present", "quadest: 9-axis when present")
    tau_acc: float = P(
        4.0,
        "s",
        "time constant of the specific force's low-pass in the almost-inertial frame",
        "chosen: the 2nd-order low-pass (cut-off √2/(2π τ)) attenuates a vehicle's 2 m/s² manoeuvre at "
        "0.2 Hz to 1° of tilt; on BROAD's split 3-5 s are within 0.04° (VQF: 3 s)",
        bounds="(0, 1e3]",
    )
    tau_mag: float = P(
        15.0,
        "s",
        "time constant of the heading correction",
        "BROAD split (docs/estimators.md): the halves chose 15 and 25 s; the shorter one (VQF: 9 s)",
        bounds="(0, 1e4]",
    )
    spin_min: float = P(
        3.0,
        "rad/s",
        "sustained rate about the vertical above which the vehicle is spinning",
        "chosen: a hand rarely keeps turning one way at 3 rad/s for seconds; a quadcopter "
        "spinning after a rotor loss turns at 10-20 rad/s",
        bounds="[0, 1e3]",
    )
    spin_rate: float = P(
        0.6,
        "rad/s",
        "each this much of sustained rate above spin_min divides the heading's time constant once more",
        "chosen: at 15 rad/s the time constant is 0.7 s, which follows "
        "a 0.5 % scale-factor drift of the spin (4 °/s) within 3°",
        bounds="(0, 1e3]",
    )
    spin_tau: float = P(
        2.0,
        "s",
        "time constant of the low-pass of the (signed) rate about the vertical",
        "chosen: a spin lasts seconds; a hand's back-and-forth turns cancel within two",
        bounds="(0, 1e3]",
    )
    bias_from_heading: bool = P(
        True,
        "-",
        "the heading correction's rate measures the vertical bias",
        "quadest's addition (VQF: inclination only)",
    )
    gyro_noise: float = P(
        0.005,
        "rad/√s",
        "gyroscope noise density (for the reported covariance)",
        "chosen: a consumer MEMS gyro (0.3 °/s/√Hz)",
        bounds="[0, 1]",
    )
    acc_corr_s: float = P(
        0.02,
        "s",
        "correlation time of unmodelled accelerations (for the reported covariance)",
        "chosen on simulator seeds 11-15 (not the checked 1-5): mean NEES 2.0 in flight and after a rotor loss",
        bounds="[0, 100]",
    )
    bias_init: float = P(0.5 * DEG, "rad/s", "initial gyro bias std", VQF + " (σ_bias,init 0.5 °/s)", bounds="[0, 1]")
    bias_drift: float = P(
        0.1 * DEG / 10.0,
        "rad/s/√s",
        "gyro bias random walk",
        "from VQF's σ_motion 0.1 °/s over its 100 s forgetting time",
        bounds="[0, 1]",
    )
    bias_motion_std: float = P(
        0.2 * DEG,
        "rad/s",
        "noise of the bias measurement from the inclination correction, per τ_acc",
        "BROAD split (docs/estimators.md): the halves chose "
        "0.2 and 0.8 °/s; the smaller one (the simulator's flights need the bias in motion)",
        bounds="(0, 1]",
    )
    bias_gain: float = P(
        0.25,
        "-",
        "largest gain of the bias loop closed by the inclination correction, in units "
        "of Δt/τ_acc (0.25: critically damped; more rings)",
        "quadest: critical damping (eq R3b)",
        bounds="(0, 1]",
    )
    bias_heading_std: float = P(
        0.2 * DEG,
        "rad/s",
        "noise of the bias measurement from the heading correction, per τ_ψ",
        "chosen: as bias_motion_std",
        bounds="(0, 1]",
    )
    bias_heading_gain: float = P(
        1.0,
        "-",
        "largest gain of the bias loop closed by the heading correction, in "
        "units of the heading's gain k (0.25: critically damped; 1: damping 0.5)",
        "chosen on simulator seeds 1-5 (normal-flight yaw 2.30° at 0.25, 2.17° at 0.5, "
        "2.09° at 1, 2.12° at 1.5); held out: seeds 21-25 2.98° → 2.48°",
        bounds="(0, 4]",
    )
    bias_rest_std: float = P(
        0.03 * DEG, "rad/s", "noise of the bias measurement at rest", VQF + " (σ_rest 0.03 °/s)", bounds="(0, 1]"
    )
    bias_clip: float = P(2.0 * DEG, "rad/s", "largest gyro bias estimated at rest", VQF + " (2 °/s)", bounds="(0, 1]")
    scale_max: float = P(
        0.005,
        "-",
        "largest gyro scale-factor error: in motion the bias (which then also absorbs "
        "the scale error times the rate) may reach bias_clip + scale_max |ω|",
        "chosen: consumer MEMS gyros are specified to ±0.5 % or better (the bebop2 preset: σ 0.3 %)",
        bounds="[0, 1]",
    )
    rest_tau: float = P(0.5, "s", "low-pass time constant of the rest detection", VQF, bounds="(0, 100]")
    rest_gyr: float = P(
        2.0 * DEG, "rad/s", "rest: largest gyro deviation from its low-pass", VQF + " (2 °/s)", bounds="(0, 10]"
    )
    rest_acc: float = P(0.5, "m/s²", "rest: largest accelerometer deviation from its low-pass", VQF, bounds="(0, 100]")
    rest_time: float = P(1.5, "s", "rest: how long both must hold", VQF, bounds="[0, 1e3]")
    mag_lp_tau: float = P(0.05, "s", "low-pass time constant of the field's norm and dip", VQF, bounds="(0, 100]")
    mag_norm_th: float = P(
        0.1, "-", "disturbed: relative deviation of the norm from the reference", VQF, bounds="(0, 10]"
    )
    mag_dip_th: float = P(
        10.0 * DEG, "rad", "disturbed: deviation of the dip from the reference", VQF + " (10°)", bounds="(0, 3.2]"
    )
    mag_ref_tau: float = P(
        20.0, "s", "time constant of the reference's update while undisturbed", VQF, bounds="(0, 1e6]"
    )
    mag_new_time: float = P(
        20.0, "s", "a new consistent field becomes the reference after this long", VQF, bounds="[0, 1e6]"
    )
    mag_new_first: float = P(5.0, "s", "the same for the first reference", VQF, bounds="[0, 1e6]")
    mag_min_undist: float = P(0.5, "s", "undisturbed after this long within the thresholds", VQF, bounds="[0, 1e3]")
    mag_max_reject: float = P(60.0, "s", "longest rejection of a disturbed field", VQF, bounds="[0, 1e6]")
    mag_reject_factor: float = P(
        2.0,
        "-",
        "after the longest rejection: the gain divided by this; rejection time "
        "is paid back this much faster while undisturbed",
        VQF,
        bounds="[1, 1e3]",
    )
    clip_learn_tau: float = P(
        1.0,
        "s",
        "time constant over which the field's noise is learnt for a clipped axis's rate (eq R4b)",
        "chosen: many magnetometer samples, yet recent",
        bounds="(0, 1e4]",
    )
    clip_heading_tau: float = P(
        0.25,
        "s",
        "longest time constant of the heading correction while a vertical axis "
        "is clipped (divided by the clipped axes' squared share about down)",
        "chosen: a 1 % rate error at 15 rad/s drifts 9 °/s, held to about 2° by 0.25 s; "
        "on the prescribed loss (seeds 1-5, in-sample) yaw varies 3.09-3.16° over 0.2-0.6 s",
        bounds="(0, 1e4]",
    )
    gyro_range: float = P(
        0.0,
        "rad/s",
        "the gyroscope's range (0: detect clipping from a flat top)",
        "quadest: unknown unless given",
        bounds="[0, 1e3]",
    )
    clip_flat: float = P(
        0.005,
        "-",
        "relative spread of a clipped axis's readings (flat top and known range)",
        "chosen: RepoIMU's calibrated readings wander by 0.3 % on a clipped axis",
        bounds="[0, 0.1]",
    )
    clip_plateau: float = P(
        1.0,
        "samples",
        "a flat top's extreme must have stood this long before a reading at it counts as clipped",
        "chosen: a ramp sets a new extreme at every sample; a clipped axis repeats its limit",
        bounds="[0, 1e3]",
    )
    clip_repeat: float = P(
        20.0,
        "samples",
        "exact repeats of a flat top's reading that confirm it a clip",
        "chosen: a quantised reading (BROAD's 0.06 °/s steps at 286 Hz) holds a few samples at "
        "a smooth peak, a clipped one as long as the clip",
        bounds="[1, 1e6]",
    )
    clip_confirm: float = P(
        3.0,
        "-",
        "standard errors by which the field's rate must exceed a flat top's readings to confirm it a clip (eq R4c)",
        "chosen: a one-sided 3σ test; a steady spin at its fastest is no clip",
        bounds="(0, 1e3]",
    )
    clip_rate_q: float = P(
        16.0,
        "rad²/s³",
        "random-walk intensity of a clipped axis's rate (eq R4b)",
        "chosen: the rate wanders 4 rad/s in 1 s (a tumble's or a swing's changes); with the "
        "field's noise learnt, the rate follows a clean field within a sample or two and "
        "averages a noisy one over a fraction of a second",
        bounds="(0, 1e6]",
    )
    clip_min_rate: float = P(
        4.3,
        "rad/s",
        "smallest rate a flat top can be clipping at",
        "chosen: the smallest common MEMS range, ±250 °/s",
        bounds="(0, 1e3]",
    )
    lever_x: float = P(
        0.0, "m", "IMU position from the centre of gravity, forward", "chosen: unknown, none", bounds="[-10, 10]"
    )
    lever_y: float = P(
        0.0, "m", "IMU position from the centre of gravity, right", "chosen: unknown, none", bounds="[-10, 10]"
    )
    lever_z: float = P(
        0.0, "m", "IMU position from the centre of gravity, down", "chosen: unknown, none", bounds="[-10, 10]"
    )
    mag_latency_s: float = P(0.0, "s", "age of a magnetometer sample", "chosen: unknown, none", bounds="[0, 1]")
    init_tau: float = P(
        0.05,
        "s",
        "the initial averaging: time constant of the recent specific force compared with its mean (eq R8)",
        "chosen: a maneuver's onset within a few tens of ms, the noise averaged over 25 samples at 500 Hz",
        bounds="(0, 100]",
    )
    init_acc: float = P(
        0.5,
        "m/s²",
        "the initial averaging ends once the recent specific force leaves its mean by this much (eq R8)",
        "chosen: VQF's rest threshold (rest_acc)",
        bounds="[0, 1e6]",
    )
    gravity: float = P(GRAVITY, "m/s²", "gravity", "standard gravity", bounds="(0, 100]")


PR = Record = params_record(RobustParams)
Coefficients = namedtuple("Coefficients", ["has_lever", "sg2"])
CO = coefficient_offsets(Coefficients)


def coefficients(p: RobustParams) -> Coefficients:
    """Whether a lever arm is given; the gyro's noise variance density."""
    return Coefficients(
        has_lever=float(p.lever_x != 0.0 or p.lever_y != 0.0 or p.lever_z != 0.0), sg2=p.gyro_noise * p.gyro_noise
    )


@njit(cache=True, inline="always")
def _qmul_s(a0, a1, a2, a3, b0, b1, b2, b3):
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


@njit(cache=True)
def _coefficients(x, p, dt):
    """Cache the Δt-dependent coefficients (recomputed only when Δt changes by over 0.1 %)."""
    if abs(dt - x[S.coef_dt]) <= 1e-3 * dt:
        return
    x[S.coef_dt] = dt
    fc = math.sqrt(2.0) / (2.0 * math.pi * p[PR.tau_acc])  # the cut-off VQF uses for its τ_acc
    K = math.tan(math.pi * min(fc * dt, 0.49))  # bilinear transform, prewarped
    nrm = 1.0 / (1.0 + math.sqrt(2.0) * K + K * K)
    x[S.coef] = K * K * nrm  # b0 (b1 = 2 b0, b2 = b0)
    x[S.coef + 1] = 2.0 * (K * K - 1.0) * nrm  # a1
    x[S.coef + 2] = (1.0 - math.sqrt(2.0) * K + K * K) * nrm  # a2
    x[S.coef + 3] = 1.0 - math.exp(-dt / p[PR.tau_acc])  # first-order equivalent gain
    x[S.coef + 4] = 1.0 - math.exp(-dt / p[PR.rest_tau])
    x[S.coef + 5] = 1.0 - math.exp(-dt / p[PR.mag_lp_tau])
    x[S.coef + 6] = 1.0 - math.exp(-dt / p[PR.init_tau])


@njit(cache=True, inline="always")
def _biquad(x, i, v, b0, a1, a2):
    """One sample of the Butterworth low-pass (transposed direct form II, ``b = b0 [1, 2, 1]``),
    state ``x[i], x[i + 1]``."""
    y = b0 * v + x[i]
    x[i] = 2.0 * b0 * v - a1 * y + x[i + 1]
    x[i + 1] = b0 * v - a2 * y
    return y


@njit(cache=True, inline="always")
def _bias_update(x, h0, h1, h2, innov, r, clip, gmax):
    """Scalar Kalman update of the bias with measurement row h, innovation and noise r; the
    gain along h at most ``gmax`` (eq R3b: ``s ≥ h P hᵀ / gmax``)."""
    Pb = S.Pb
    ph0 = x[Pb] * h0 + x[Pb + 1] * h1 + x[Pb + 2] * h2
    ph1 = x[Pb + 3] * h0 + x[Pb + 4] * h1 + x[Pb + 5] * h2
    ph2 = x[Pb + 6] * h0 + x[Pb + 7] * h1 + x[Pb + 8] * h2
    hph = h0 * ph0 + h1 * ph1 + h2 * ph2
    s = max(hph + r, hph / gmax)
    if not s > 0.0:
        return
    k0, k1, k2 = ph0 / s, ph1 / s, ph2 / s
    x[S.bias] = min(clip, max(-clip, x[S.bias] + k0 * innov))
    x[S.bias + 1] = min(clip, max(-clip, x[S.bias + 1] + k1 * innov))
    x[S.bias + 2] = min(clip, max(-clip, x[S.bias + 2] + k2 * innov))
    x[Pb] -= k0 * ph0
    x[Pb + 1] -= k0 * ph1
    x[Pb + 2] -= k0 * ph2
    x[Pb + 3] -= k1 * ph0
    x[Pb + 4] -= k1 * ph1
    x[Pb + 5] -= k1 * ph2
    x[Pb + 6] -= k2 * ph0
    x[Pb + 7] -= k2 * ph1
    x[Pb + 8] -= k2 * ph2


@njit(cache=True, inline="always")
def _mag_rate_terms(mi, mj, mk, dj, dk, wj, wk):
    """Eq R4 for axis i, (i, j, k) cyclic: ``ṁ = −ω × m`` gives ``ṁ_j + ω_k m_i = ω_i m_k`` and
    ``ṁ_k − ω_j m_i = −ω_i m_j``, whose least-squares solution is ``ω_i = num / den`` with
    ``num = m_k (ṁ_j + ω_k m_i) − m_j (ṁ_k − ω_j m_i)`` and ``den = m_j² + m_k²`` (a field along the
    axis says nothing of its rate). ``m`` the mid-point of two samples, ``d`` their difference over
    the interval, ``w`` the other axes' mean rates over it."""
    return mk * (dj + wk * mi) - mj * (dk - wj * mi), mj * mj + mk * mk


@njit(cache=True, inline="always")
def _clip_rate_update(x, p, i, num, den, wi, mdt, kl):
    """Eq R4b: the rate of axis i over the last magnetometer interval. While the axis reads
    within range its mean reading ``wi`` is the rate, and the field's noise (the variance ``V`` of
    ``num − wi den``) is learnt (gain ``kl``). While it is clipped a scalar Kalman filter with a
    random-walk rate (intensity ``q``, ``clip_rate_q``) follows the field's rate:
    ``P ← P + q Δt``, ``K = P / (P + V / den²)``, ``ω ← ω + K (num / den − ω)``,
    ``P ← (1 − K) P``. Its time constant, about ``sqrt(V Δt / (q den²))``, follows from the data:
    a noisy field (the horizontal share of a spin about down) is averaged over a fraction of a
    second, a clean one (a hand-held stick's) followed within a sample or two.

    Eq R4c: on a flat top not yet confirmed a clip (``flat``), once ``V`` has been learnt for
    ``clip_learn_tau``, the field's rate in excess of the reading, ``s (num / den − wi)`` (``s``
    the reading's sign) with variance ``V / den²``, is summed with inverse-variance weights;
    once ``Σ excess den²/V / sqrt(Σ den²/V)`` passes
    ``clip_confirm`` standard errors, and the weighted mean excess the top's spread
    (``clip_flat``), the top's level is the axis's limit for that sign."""
    if x[S.gclip + i] == 0.0:
        if x[S.gflat + i] != 0.0:
            if x[S.Vt + i] >= p[PR.clip_learn_tau] and x[S.Vn + i] > 0.0 and den > 0.0 and x[S.flat + i] != 0.0:
                sg = 1.0 if x[S.level + i] > 0.0 else -1.0
                x[S.ev_s + i] += sg * (num - wi * den) * den / x[S.Vn + i]
                x[S.ev_w + i] += den * den / x[S.Vn + i]
                # significant, and beyond the flat top's own spread (a quantised reading's
                # rounding errs one way for as long as it holds its value)
                if (
                    x[S.ev_s + i] > p[PR.clip_confirm] * math.sqrt(x[S.ev_w + i])
                    and x[S.ev_s + i] > p[PR.clip_flat] * abs(x[S.level + i]) * x[S.ev_w + i]
                ):
                    if sg > 0.0:
                        x[S.lim_pos + i] = x[S.level + i]
                    else:
                        x[S.lim_neg + i] = x[S.level + i]
        else:
            # a running mean until clip_learn_tau has passed, then exponential forgetting
            e = num - wi * den
            x[S.Vt + i] += mdt
            x[S.Vn + i] += max(kl, mdt / x[S.Vt + i]) * (e * e - x[S.Vn + i])
        x[S.rate + i] = wi
        x[S.Pw + i] = 0.0
    else:
        if den <= 0.0:
            return
        pw = x[S.Pw + i] + p[PR.clip_rate_q] * mdt
        r = x[S.Vn + i] / (den * den)
        k = pw / (pw + r) if pw + r > 0.0 else 1.0
        x[S.rate + i] += k * (num / den - x[S.rate + i])
        x[S.Pw + i] = (1.0 - k) * pw


@njit(cache=True, inline="always")
def _detect_clip(x, p, i, g):
    """Item 6: whether axis i's reading ``g`` is clipped. With a known range, a reading within
    ``clip_flat`` of it. Otherwise a flat top is a candidate: beyond ``clip_min_rate``, within
    ``clip_flat`` of the previous reading and of the extreme of its sign, an extreme that has
    stood ``clip_plateau`` samples (a ramp sets a new one at every sample); it continues while
    the readings stay within ``clip_flat`` of its first (a clipped axis cannot read more, a
    ramp soon does). The signs are tracked apart: calibrated readings clip at +416.6 and
    −421.6 °/s on RepoIMU's TStick trial 5, each wandering by a few tenths of a percent with the
    other axes' calibration terms. A candidate is a clip once its limit is confirmed, by a
    reading repeated exactly ``clip_repeat`` times (a quantised reading repeats at a smooth peak
    for a few samples; a clipped raw value for as long as the clip) or by the field (eq R4c, in
    the magnetometer step): a steady spin at its fastest is a flat top too, and is not a clip.
    A confirmed limit is the sensor's: later readings within ``clip_flat`` of it are clipped at
    once, and a reading beyond it erases it."""
    a = abs(g)
    tol = p[PR.clip_flat] * a
    if p[PR.gyro_range] > 0.0:
        return a >= p[PR.gyro_range] - tol
    if a < p[PR.clip_min_rate]:
        x[S.flat + i] = 0.0
        return False
    x[S.peak_n + i] += 1.0
    x[S.trough_n + i] += 1.0
    if g > x[S.peak + i]:
        x[S.peak + i] = g
        x[S.peak_n + i] = 0.0
    if g < x[S.trough + i]:
        x[S.trough + i] = g
        x[S.trough_n + i] = 0.0
    lim = x[S.lim_pos + i] if g > 0.0 else x[S.lim_neg + i]
    if lim != 0.0 and a > abs(lim) + tol:  # read beyond: it was no limit
        if g > 0.0:
            x[S.lim_pos + i] = 0.0
        else:
            x[S.lim_neg + i] = 0.0
        lim = 0.0
    if lim != 0.0 and abs(a - abs(lim)) <= tol:
        x[S.flat + i] = 0.0
        return True
    if x[S.flat + i] != 0.0 and g * x[S.level + i] > 0.0:
        cand = abs(a - abs(x[S.level + i])) <= tol
    else:
        if g > 0.0:
            cand = g >= x[S.peak + i] - tol and x[S.peak_n + i] >= p[PR.clip_plateau]
        else:
            cand = g <= x[S.trough + i] + tol and x[S.trough_n + i] >= p[PR.clip_plateau]
        cand = cand and abs(g - x[S.gprev + i]) <= tol
        x[S.level + i] = g
        x[S.rep + i] = 0.0
        x[S.ev_s + i] = 0.0
        x[S.ev_w + i] = 0.0
    if not cand:
        x[S.flat + i] = 0.0
        return False
    x[S.flat + i] = 1.0
    x[S.gflat + i] = 1.0
    x[S.rep + i] = x[S.rep + i] + 1.0 if g == x[S.gprev + i] else 0.0
    if x[S.rep + i] >= p[PR.clip_repeat]:  # repeated exactly for long: the limit
        if g > 0.0:
            x[S.lim_pos + i] = g
        else:
            x[S.lim_neg + i] = g
        x[S.flat + i] = 0.0
        return True
    return False


@njit(cache=True, fastmath=FASTMATH)
def robust_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    have_mag = (
        p[PR.use_mag] != 0.0
        and not (np.isnan(mag[0]) or np.isnan(mag[1]) or np.isnan(mag[2]))
        and (mag[0] != 0.0 or mag[1] != 0.0 or mag[2] != 0.0)
    )
    _coefficients(x, p, dt)
    b0, a1, a2, k_acc, k_rest, k_mlp = (
        x[S.coef],
        x[S.coef + 1],
        x[S.coef + 2],
        x[S.coef + 3],
        x[S.coef + 4],
        x[S.coef + 5],
    )
    x[S.mag_dt] += dt
    # -- gyro clipping (6): a flat top at the extreme of its sign, or the known range -------------
    w0, w1, w2 = gyr[0], gyr[1], gyr[2]
    nclip = 0
    for i in range(3):
        g = gyr[i]
        clipped = _detect_clip(x, p, i, g)
        x[S.gprev + i] = g
        x[S.gsum + i] += g * dt
        if clipped:
            x[S.clipped + i] = 1.0
            x[S.gclip + i] = 1.0
            nclip += 1
        else:
            x[S.clipped + i] = 0.0
            x[S.debt + i] = 0.0
    # the magnetometer's latency is rotated out with the last rate held on a clipped axis
    if nclip:
        if x[S.clipped] != 0.0:
            w0 = x[S.hold]
        if x[S.clipped + 1] != 0.0:
            w1 = x[S.hold + 1]
        if x[S.clipped + 2] != 0.0:
            w2 = x[S.hold + 2]
    # -- magnetometer: latency (9) and the rate of a clipped axis (6) -----------------------------
    m0 = m1 = m2 = 0.0
    if have_mag:
        m0, m1, m2 = mag[0], mag[1], mag[2]
        if p[PR.mag_latency_s] > 0.0:  # eq R5: m ← Exp(−ω τ) m
            t = p[PR.mag_latency_s]
            qw, qx, qy, qz = 1.0, 0.0, 0.0, 0.0
            th = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) * t
            if th > 0.0:
                s = math.sin(0.5 * th) / (th / t)
                qw, qx, qy, qz = math.cos(0.5 * th), -w0 * s, -w1 * s, -w2 * s
            m0, m1, m2 = rotate_s(qw, qx, qy, qz, m0, m1, m2)
        if np.isfinite(x[S.mprev]) and x[S.mag_dt] > 0.0:
            mdt = x[S.mag_dt]
            kl = 1.0 - math.exp(-mdt / p[PR.clip_learn_tau])
            c0, c1, c2 = 0.5 * (m0 + x[S.mprev]), 0.5 * (m1 + x[S.mprev + 1]), 0.5 * (m2 + x[S.mprev + 2])
            d0, d1, d2 = (m0 - x[S.mprev]) / mdt, (m1 - x[S.mprev + 1]) / mdt, (m2 - x[S.mprev + 2]) / mdt
            # the interval's mean rates; a clipped axis's from its estimate
            v0 = x[S.gsum] / mdt if x[S.gclip] == 0.0 else x[S.rate]
            v1 = x[S.gsum + 1] / mdt if x[S.gclip + 1] == 0.0 else x[S.rate + 1]
            v2 = x[S.gsum + 2] / mdt if x[S.gclip + 2] == 0.0 else x[S.rate + 2]
            nu, de = _mag_rate_terms(c0, c1, c2, d1, d2, v1, v2)
            _clip_rate_update(x, p, 0, nu, de, v0, mdt, kl)
            nu, de = _mag_rate_terms(c1, c2, c0, d2, d0, v2, v0)
            _clip_rate_update(x, p, 1, nu, de, v1, mdt, kl)
            nu, de = _mag_rate_terms(c2, c0, c1, d0, d1, v0, v1)
            _clip_rate_update(x, p, 2, nu, de, v2, mdt, kl)
        for i in range(3):
            x[S.gsum + i] = 0.0
            x[S.gclip + i] = 0.0
            x[S.gflat + i] = 0.0
        x[S.mprev], x[S.mprev + 1], x[S.mprev + 2] = m0, m1, m2
    # a clipped axis: the field's rate (eq R4b), never below the limit; what the limit adds beyond
    # that rate is owed and paid back once the rate exceeds the limit, so the bound does not
    # rectify the estimate's noise into a drift
    if nclip:
        for i in range(3):
            if x[S.clipped + i] != 0.0:
                g = gyr[i]
                a = abs(g)
                sg = 1.0 if g > 0.0 else -1.0
                r = sg * x[S.rate + i] + x[S.debt + i] / dt
                if r > a:
                    x[S.hold + i] = sg * r
                    x[S.debt + i] = 0.0
                else:
                    x[S.hold + i] = g
                    x[S.debt + i] = (r - a) * dt
        w0 = x[S.hold] if x[S.clipped] != 0.0 else gyr[0]
        w1 = x[S.hold + 1] if x[S.clipped + 1] != 0.0 else gyr[1]
        w2 = x[S.hold + 2] if x[S.clipped + 2] != 0.0 else gyr[2]
    # -- lever arm (7) ----------------------------------------------------------------------
    f0, f1, f2 = acc[0], acc[1], acc[2]
    if c[CO.has_lever]:
        r0, r1, r2 = p[PR.lever_x], p[PR.lever_y], p[PR.lever_z]
        c0, c1, c2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0  # ω × r
        f0 -= w1 * c2 - w2 * c1
        f1 -= w2 * c0 - w0 * c2
        f2 -= w0 * c1 - w1 * c0
    fn = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    # -- initialisation: the strapdown starts from q0 (or the identity), the rest detection's
    # low-passes from the first sample ---------------------------------------------------------------
    if x[INIT] == 0.0:
        if not fn > 0.0:
            return
        x[INIT] = 1.0
    if x[S.mean_n] == 0.0:
        for i in range(3):
            x[S.rest_g + i] = gyr[i]
            x[S.rest_a + i] = acc[i]
    # -- strapdown in I (1) ----------------------------------------------------------------------
    # a clipped axis's rate is the true rate (from the field) or a bound: no bias is removed from it
    u0 = w0 - (x[S.bias] if x[S.clipped] == 0.0 else 0.0)
    u1 = w1 - (x[S.bias + 1] if x[S.clipped + 1] == 0.0 else 0.0)
    u2 = w2 - (x[S.bias + 2] if x[S.clipped + 2] == 0.0 else 0.0)
    clip_b = p[PR.bias_clip] + p[PR.scale_max] * math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    th = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2) * dt
    if th > 0.0:
        s = math.sin(0.5 * th) / th * dt
        gw, gx, gy, gz = x[S.qg], x[S.qg + 1], x[S.qg + 2], x[S.qg + 3]
        a0_, a1_, a2_, a3_ = _qmul_s(gw, gx, gy, gz, math.cos(0.5 * th), u0 * s, u1 * s, u2 * s)
        x[S.qg], x[S.qg + 1], x[S.qg + 2], x[S.qg + 3] = normalize_s(a0_, a1_, a2_, a3_)
    gw, gx, gy, gz = x[S.qg], x[S.qg + 1], x[S.qg + 2], x[S.qg + 3]
    iw, ix, iy, iz = x[S.qi], x[S.qi + 1], x[S.qi + 2], x[S.qi + 3]
    # -- rest detection and the bias at rest (4) ----------------------------------------------------
    dg = da = 0.0
    for i in range(3):
        x[S.rest_g + i] += k_rest * (gyr[i] - x[S.rest_g + i])
        x[S.rest_a + i] += k_rest * (acc[i] - x[S.rest_a + i])
        dg += (gyr[i] - x[S.rest_g + i]) ** 2
        da += (acc[i] - x[S.rest_a + i]) ** 2
    # every sample must be within the thresholds (as VQF's): a mean square would take a slow
    # translation for rest (BROAD's trial 11: 1.1° -> 2.6°)
    rg0, rg1, rg2 = x[S.rest_g], x[S.rest_g + 1], x[S.rest_g + 2]
    rest_rate2 = 3.0 * (p[PR.bias_clip] + p[PR.rest_gyr]) ** 2  # the largest squared rate at rest
    still = (
        dg <= p[PR.rest_gyr] * p[PR.rest_gyr]
        and da <= p[PR.rest_acc] * p[PR.rest_acc]
        and nclip == 0
        and rg0 * rg0 + rg1 * rg1 + rg2 * rg2 <= rest_rate2
    )
    x[S.rest_t] = x[S.rest_t] + dt if still else 0.0
    at_rest = x[S.rest_t] >= p[PR.rest_time]
    # bias covariance: random walk; the variance capped at the initial one (the vertical axis is
    # weakly observable without a magnetometer)
    qb = p[PR.bias_drift] * p[PR.bias_drift] * dt
    cap = p[PR.bias_init] * p[PR.bias_init]
    for i in range(3):
        d = S.Pb + 4 * i
        x[d] = min(x[d] + qb, cap)
    if at_rest:
        r = p[PR.bias_rest_std] * p[PR.bias_rest_std]
        _bias_update(x, 1.0, 0.0, 0.0, rg0 - x[S.bias], r, p[PR.bias_clip], 1.0)
        _bias_update(x, 0.0, 1.0, 0.0, rg1 - x[S.bias + 1], r, p[PR.bias_clip], 1.0)
        _bias_update(x, 0.0, 0.0, 1.0, rg2 - x[S.bias + 2], r, p[PR.bias_clip], 1.0)
    # -- inclination (2) ----------------------------------------------------------------------------
    ew, ex, ey, ez = _qmul_s(iw, ix, iy, iz, gw, gx, gy, gz)  # q_Eb
    pt = x[S.Pt]
    sb2 = (x[S.Pb] + x[S.Pb + 4] + x[S.Pb + 8]) / 3.0
    pt += (c[CO.sg2] + p[PR.tau_acc] * sb2) * dt
    if fn > 0.0:
        fI0, fI1, fI2 = rotate_s(gw, gx, gy, gz, f0, f1, f2)
        n = x[S.mean_n]
        if n >= 0.0:  # the first τ_acc: a running mean (converges at once, no initial transient)
            n += 1.0
            y0 = x[S.lpy] + (fI0 - x[S.lpy]) / n
            y1 = x[S.lpy + 1] + (fI1 - x[S.lpy + 1]) / n
            y2 = x[S.lpy + 2] + (fI2 - x[S.lpy + 2]) / n
            kk = max(k_acc, 1.0 / n)
            # eq R8 (item 11): the averaging assumes no sustained acceleration; the specific
            # force's mean over the last init_tau leaving the mean so far by more than init_acc
            # and than its noise allows (χ²(3) at 99.9 %: 16.3 times the variance of the
            # difference) ends it, for a start that was still
            if n == 1.0 and gyr[0] ** 2 + gyr[1] ** 2 + gyr[2] ** 2 > rest_rate2:
                x[S.moved] = -1.0  # started turning: no still reference, the whole averaging
            if x[S.moved] == 0.0:
                k_init = x[S.coef + 6]
                ks = max(k_init, 1.0 / n)
                x[S.ys] += ks * (fI0 - x[S.ys])
                x[S.ys + 1] += ks * (fI1 - x[S.ys + 1])
                x[S.ys + 2] += ks * (fI2 - x[S.ys + 2])
                if n > 1.0:  # successive differences: var(f_k - f_k-1) = 2 σ²
                    e0, e1, e2 = fI0 - x[S.fprev], fI1 - x[S.fprev + 1], fI2 - x[S.fprev + 2]
                    x[S.fvar] += (0.5 * (e0 * e0 + e1 * e1 + e2 * e2) - x[S.fvar]) / (n - 1.0)
                x[S.fprev], x[S.fprev + 1], x[S.fprev + 2] = fI0, fI1, fI2
                # against the mean as it was when the recent force last agreed with it (within
                # half the threshold): a slow onset, which the mean would follow, still shows in full
                dy0, dy1, dy2 = x[S.ys] - x[S.yok], x[S.ys + 1] - x[S.yok + 1], x[S.ys + 2] - x[S.yok + 2]
                dev2 = dy0 * dy0 + dy1 * dy1 + dy2 * dy2
                thr2 = max(p[PR.init_acc] * p[PR.init_acc], 16.3 * x[S.fvar] * (ks / (2.0 - ks) + 1.0 / n))
                if n == 1.0 or dev2 <= 0.25 * thr2:
                    x[S.yok], x[S.yok + 1], x[S.yok + 2] = y0, y1, y2
                elif dev2 > thr2:
                    x[S.moved] = 1.0  # the low-pass starts from the mean before the acceleration
                    y0, y1, y2 = x[S.yok], x[S.yok + 1], x[S.yok + 2]
            if n * dt >= p[PR.tau_acc] or x[S.moved] > 0.0:
                n = -1.0
                for i, yi in enumerate((y0, y1, y2)):  # the low-pass starts in steady state at the mean
                    x[S.lp + 2 * i] = yi - b0 * yi
                    x[S.lp + 2 * i + 1] = b0 * yi - a2 * yi
            x[S.mean_n] = n
        else:
            kk = k_acc
            y0 = _biquad(x, S.lp, fI0, b0, a1, a2)
            y1 = _biquad(x, S.lp + 2, fI1, b0, a1, a2)
            y2 = _biquad(x, S.lp + 4, fI2, b0, a1, a2)
        x[S.lpy], x[S.lpy + 1], x[S.lpy + 2] = y0, y1, y2
        v0, v1, v2 = rotate_s(iw, ix, iy, iz, -y0, -y1, -y2)  # down, as estimated, in E
        vn = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if vn > 0.0:
            v0, v1, v2 = v0 / vn, v1 / vn, v2 / vn
            # eq R1: the shortest rotation taking v onto e_z = [0, 0, 1]
            cw = math.sqrt(max(0.0, 0.5 * (1.0 + v2)))
            if cw > 1e-6:
                cx, cy = 0.5 * v1 / cw, -0.5 * v0 / cw
            else:
                cx, cy = 1.0, 0.0
            a0_, a1_, a2_, a3_ = _qmul_s(cw, cx, cy, 0.0, iw, ix, iy, iz)
            iw, ix, iy, iz = normalize_s(a0_, a1_, a2_, a3_)
            x[S.qi], x[S.qi + 1], x[S.qi + 2], x[S.qi + 3] = iw, ix, iy, iz
            # eq R3: the correction's rate measures the horizontal drift of a bias error
            # ... while the scale-factor error at this rate is below the bias it resolves (eq R3c)
            rate2 = u0 * u0 + u1 * u1 + u2 * u2
            if not at_rest and nclip == 0 and n < 0.0 and p[PR.scale_max] ** 2 * rate2 <= p[PR.bias_motion_std] ** 2:
                sn = math.sqrt(cx * cx + cy * cy)
                ang = 2.0 * math.atan2(sn, cw)
                sc = ang / sn / dt if sn > 1e-12 else 2.0 / dt
                y_n, y_e = cx * sc, cy * sc  # E-frame rate of the correction, north and east
                r = p[PR.bias_motion_std] * p[PR.bias_motion_std] * p[PR.tau_acc] / dt
                # rows of R(q_Eb): body -> E
                h00, h01, h02 = 1 - 2 * (ey * ey + ez * ez), 2 * (ex * ey - ew * ez), 2 * (ex * ez + ew * ey)
                h10, h11, h12 = 2 * (ex * ey + ew * ez), 1 - 2 * (ex * ex + ez * ez), 2 * (ey * ez - ew * ex)
                gmax = p[PR.bias_gain] * dt / p[PR.tau_acc]
                _bias_update(x, h00, h01, h02, -y_n, r, clip_b, gmax)
                _bias_update(x, h10, h11, h12, -y_e, r, clip_b, gmax)
        # accelerometer direction noise (adaptive) for the reported covariance (eq R6)
        fe2 = rotate_s(ew, ex, ey, ez, f0, f1, f2)[2]
        cosang = min(1.0, max(-1.0, -fe2 / fn))
        ang2 = math.acos(cosang) ** 2
        x[S.Ra] += k_rest * (ang2 - x[S.Ra]) if x[S.Ra] > 0.0 else ang2
        pt = (1.0 - kk) ** 2 * pt + kk * kk * x[S.Ra] * (1.0 + 2.0 * p[PR.acc_corr_s] / dt)
    x[S.Pt] = pt
    # -- heading (3, 5, 8) -------------------------------------------------------------------------------
    ew, ex, ey, ez = _qmul_s(iw, ix, iy, iz, gw, gx, gy, gz)
    h20, h21, h22 = 2 * (ex * ez - ew * ey), 2 * (ey * ez + ew * ex), 1 - 2 * (ex * ex + ey * ey)
    wd = h20 * u0 + h21 * u1 + h22 * u2  # rate about down
    x[S.spin] += (1.0 - math.exp(-dt / p[PR.spin_tau])) * (wd - x[S.spin])
    # eq R7: a sustained spin drifts the heading by the scale-factor error times its rate
    spin = abs(x[S.spin])
    tau = p[PR.tau_mag] / (1.0 + max(0.0, spin - p[PR.spin_min]) / p[PR.spin_rate])
    # a clipped axis's rate error turns the heading by its share about down (the cosine between
    # the axis and down, squared): a spin's vertical axis fully, a stick's horizontal one not at
    # all (there it is the tilt that errs, and the field's heading with it)
    s0, s1, s2 = h20 * h20 * x[S.clipped], h21 * h21 * x[S.clipped + 1], h22 * h22 * x[S.clipped + 2]
    if nclip:
        share = s0 + s1 + s2
        if share > 0.0:
            tau = min(tau, p[PR.clip_heading_tau] / min(1.0, share))
    ph = x[S.Ph]
    if x[S.ref] > 0.0 or have_mag:
        # eq R6: the heading's drift rate has the variance of the vertical bias, of the scale error
        # times the spin, and of a clipped axis's rate from the field
        pbv = (
            h20 * (x[S.Pb] * h20 + x[S.Pb + 1] * h21 + x[S.Pb + 2] * h22)
            + h21 * (x[S.Pb + 3] * h20 + x[S.Pb + 4] * h21 + x[S.Pb + 5] * h22)
            + h22 * (x[S.Pb + 6] * h20 + x[S.Pb + 7] * h21 + x[S.Pb + 8] * h22)
        )
        drift2 = pbv + (p[PR.scale_max] * spin) ** 2
        if nclip:  # a clipped axis's rate error (its variance from eq R4b) seen about down
            drift2 += s0 * x[S.Pw] + s1 * x[S.Pw + 1] + s2 * x[S.Pw + 2]
        ph += (c[CO.sg2] + tau * drift2) * dt
    delta = x[S.delta]
    mupd = 0.0
    if have_mag:
        mdt = x[S.mag_dt]
        x[S.mag_dt] = 0.0
        me0, me1, me2 = rotate_s(ew, ex, ey, ez, m0, m1, m2)
        mn = math.sqrt(me0 * me0 + me1 * me1 + me2 * me2)
        mh = math.sqrt(me0 * me0 + me1 * me1)
        if mn > 0.0:
            dip = math.atan2(me2, mh)
            # disturbance detection (5): norm and dip against a reference
            if x[S.ref] == 0.0:
                x[S.ref], x[S.ref + 1] = mn, dip
                x[S.cur], x[S.cur + 1] = mn, dip
                x[S.cand], x[S.cand + 1] = mn, dip
                x[S.undist_t] = p[PR.mag_min_undist]
            km = 1.0 - math.exp(-mdt / p[PR.mag_lp_tau])
            x[S.cur] += km * (mn - x[S.cur])
            x[S.cur + 1] += km * (dip - x[S.cur + 1])
            cn, cd = x[S.cur], x[S.cur + 1]
            ok = abs(cn - x[S.ref]) <= p[PR.mag_norm_th] * x[S.ref] and abs(cd - x[S.ref + 1]) <= p[PR.mag_dip_th]
            if ok:
                x[S.undist_t] += mdt
                if x[S.undist_t] >= p[PR.mag_min_undist]:
                    x[S.disturbed] = 0.0
                    kr = 1.0 - math.exp(-mdt / p[PR.mag_ref_tau])
                    x[S.ref] += kr * (cn - x[S.ref])
                    x[S.ref + 1] += kr * (cd - x[S.ref + 1])
                    x[S.reject_t] = max(0.0, x[S.reject_t] - p[PR.mag_reject_factor] * mdt)
                    x[S.ref_conf] = 1.0 if x[S.undist_t] >= p[PR.mag_new_first] else x[S.ref_conf]
                x[S.cand], x[S.cand + 1], x[S.cand_t] = cn, cd, 0.0
            else:
                x[S.undist_t] = 0.0
                x[S.disturbed] = 1.0
                x[S.reject_t] += mdt
                # a new field that stays consistent becomes the reference
                if abs(cn - x[S.cand]) <= p[PR.mag_norm_th] * x[S.cand] and abs(cd - x[S.cand + 1]) <= p[PR.mag_dip_th]:
                    x[S.cand_t] += mdt
                    kc = 1.0 - math.exp(-mdt / p[PR.mag_lp_tau]) if x[S.cand_t] < 1.0 else mdt / x[S.cand_t]
                    x[S.cand] += kc * (cn - x[S.cand])
                    x[S.cand + 1] += kc * (cd - x[S.cand + 1])
                else:
                    x[S.cand], x[S.cand + 1], x[S.cand_t] = cn, cd, 0.0
                need = p[PR.mag_new_time] if x[S.ref_conf] != 0.0 else p[PR.mag_new_first]
                if x[S.cand_t] >= need:
                    x[S.ref], x[S.ref + 1] = x[S.cand], x[S.cand + 1]
                    x[S.disturbed], x[S.reject_t], x[S.ref_conf] = 0.0, 0.0, 1.0
                    x[S.undist_t] = p[PR.mag_min_undist]
            gain_div = 1.0
            if x[S.disturbed] != 0.0:
                gain_div = 0.0 if x[S.reject_t] <= p[PR.mag_max_reject] else 1.0 / p[PR.mag_reject_factor]
            if gain_div > 0.0 and mh > 0.0:
                dm = -math.atan2(me1, me0)  # eq R2
                x[S.mag_n] += 1.0
                k = 1.0 - math.exp(-mdt / tau)
                if x[S.moved] <= 0.0 or x[S.mag_n] == 1.0:
                    k = max(k, 1.0 / x[S.mag_n])
                k *= gain_div
                e = wrap_angle(dm - delta)
                if x[S.mag_n] == 1.0:
                    ph = x[S.Rm] = 0.25  # first sample: the heading from one noisy field (0.5 rad chosen)
                else:
                    x[S.Rm] += k_mlp * (e * e - x[S.Rm])
                    ph = (1.0 - k) ** 2 * ph + k * k * x[S.Rm]
                delta = wrap_angle(delta + k * e)
                mupd = 1.0
                # the heading correction's rate measures the vertical drift of a bias error
                steady = x[S.mag_n] * k > 1.0 or x[S.moved] > 0.0
                if (
                    p[PR.bias_from_heading] != 0.0 and steady and nclip == 0 and not at_rest and x[S.disturbed] == 0.0
                ):  # steady state only: not the initial averaging (k = 1/n)
                    r = p[PR.bias_heading_std] * p[PR.bias_heading_std] * tau / mdt
                    _bias_update(x, h20, h21, h22, -(k * e) / mdt, r, clip_b, p[PR.bias_heading_gain] * k)
    if x[S.ref] == 0.0:
        ph = UNKNOWN_HEADING_VAR
    x[S.Ph] = min(ph, UNKNOWN_HEADING_VAR)
    x[S.delta] = delta
    # -- output: q_nb = Rz(δ) ⊗ q_EI ⊗ q_Ib ---------------------------------------------------------------
    cz, sz = math.cos(0.5 * delta), math.sin(0.5 * delta)
    x[0], x[1], x[2], x[3] = _qmul_s(cz, 0.0, 0.0, sz, ew, ex, ey, ez)
    diag[0] = 1.0 if at_rest else 0.0
    diag[1] = x[S.disturbed]
    diag[2] = float(nclip)
    diag[3], diag[4], diag[5] = x[S.bias], x[S.bias + 1], x[S.bias + 2]
    diag[6] = x[S.Pt]
    diag[7] = x[S.Ph]
    diag[8] = mupd
    publish(x)


@njit(cache=True, fastmath=FASTMATH)
def robust_run(x, p, c, dt, gyr, acc, mag, q_out, diag_out):
    """Batch: the same step over every sample, in compiled code."""
    for k in range(len(dt)):
        robust_step(x, p, c, gyr[k], acc[k], mag[k], dt[k], diag_out[k])
        q_out[k] = x[Q_OUT : Q_OUT + 4]  # published: in the geographic frame


def robust_stream(x, nx, p, n_p, c, nc, gyr, acc, mag, dt, diag, nd):
    """Streaming: the same step on the raw buffers of the C call; 1 if it raised (base.stream_address)."""
    try:
        robust_step(
            carray(x, nx),
            carray(p, n_p),
            carray(c, nc),
            carray(gyr, 3),
            carray(acc, 3),
            carray(mag, 3),
            dt,
            carray(diag, nd),
        )
    except Exception:  # noqa: BLE001 -- a C callback cannot raise: the C call does, from the status
        return 1
    return 0


class Robust(Estimator):
    """quadest's own estimator. Diagnostics: ``rest`` (1 at rest), ``mag_disturbed``,
    ``clipped_axes``, the bias ``bias_x/y/z`` (rad/s), the reported error variances ``var_tilt``
    (about north and about east, each) and ``var_heading`` (about down), rad², and
    ``mag_update``."""

    name = "robust"
    Params = RobustParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = S.end
    diag_names = (
        "rest",
        "mag_disturbed",
        "clipped_axes",
        "bias_x",
        "bias_y",
        "bias_z",
        "var_tilt",
        "var_heading",
        "mag_update",
    )
    step = staticmethod(robust_step)
    batch = staticmethod(robust_run)
    stream = staticmethod(robust_stream)

    def _init_state(self, x):
        p = self.params
        x[S.qg : S.qg + 4] = x[0:4]  # q0 (in the magnetic frame) or the identity: δ = 0, q_EI = 1
        x[S.qi] = 1.0
        x[S.Pb : S.Pb + 9] = (np.eye(3) * p.bias_init**2).ravel()
        x[S.mprev : S.mprev + 3] = np.nan
        x[S.Pt] = 0.0
        x[S.Ph] = UNKNOWN_HEADING_VAR
        x[S.coef_dt] = -1.0
