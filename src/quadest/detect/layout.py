"""The rotor-failure detector's layouts (docs/detection.md): its state, its model of the
vehicle and the fast test's ring as named offsets into the float arrays its compiled step
reads, and its diagnostics per sample. Compiled code reads a slot by name
(``x[STATE.eta + i]``), so no slot count is written anywhere else."""

from __future__ import annotations

from quadest.records import layout

MAX_ROTORS = 8
H_TAU = 0.004  # s: the low-pass of the rotors' momentum whose change the model reads (chosen: two samples at 500 Hz)
F_TAU = 0.02  # s: the low-pass of the accelerometer's x and y for the rotors' drag (chosen: above vibration)
NS = 3 + MAX_ROTORS  # the filter's largest state: rate and effectiveness
GLR_MAX = 32  # samples: the longest window of the fast test
ROW = layout(  # one sample in the fast test's ring
    ("gyr", 3),
    ("base", 3),  # the rate change without the rotors
    ("b", 3 * MAX_ROTORS),  # the rate change per unit effectiveness, ``b + j·MAX_ROTORS + i``
    ("thrust", MAX_ROTORS),  # thrust per mass per unit effectiveness (right after ``b``: its fourth row)
    ("eta", MAX_ROTORS),
    ("acc_z", 1),
)
GLR_ROW = ROW.end
STATE = layout(
    ("w", 3),
    ("eta", MAX_ROTORS),
    ("P", NS * NS),
    ("omega", MAX_ROTORS),  # the rotor speeds over the last interval (root mean square)
    ("omega_end", MAX_ROTORS),  # at its end
    ("s_lost", MAX_ROTORS),
    ("s_damaged", MAX_ROTORS),
    ("init", 1),
    ("time", 1),
    ("lost", 1),  # the rotor found lost (-1: none), the time, the effectiveness left
    ("lost_t", 1),
    ("lost_eta", 1),
    ("damaged", 1),
    ("damaged_t", 1),
    ("damaged_eta", 1),
    ("gyr_prev", 6),  # the last two gyroscope readings, then the estimate of its noise's variance per axis
    ("gyr_var", 3),
    ("samples", 1),
    ("contact_t", 1),  # when the accelerometer last read a push the rotors cannot make (-inf: never)
    ("landed", 1),  # 1 from a contact until the rotors carry the weight again
    ("cut_t", 1),  # when rotors were last commanded at their lowest speed together (-inf: never)
    ("h_lp", MAX_ROTORS),  # each rotor's angular momentum I_p s_i Ω_i, low-passed over H_TAU
    ("f_lp", 2),  # the accelerometer's x and y less the yaw rate's rotor drag, low-passed over F_TAU
    ("glr", GLR_MAX * GLR_ROW),  # the fast test's ring of the last samples
    ("glr_n", 1),  # samples in it
    ("glr_head", 1),  # the slot of the next one
    ("glr_r", 4),  # scratch of the fast test: sums over its window (below)
    ("glr_sig", 4 * MAX_ROTORS),
    ("B", 3 * MAX_ROTORS),  # scratch of one step: the input matrix, F P's rows, P h, h
    ("FP", 3 * NS),
    ("ph", NS),
    ("h", NS),
    ("scale", 3),  # the rotors' moment per axis against the model's, learnt in flight (1: the model's)
    ("scale_y", 6),  # per axis, the measured rate change less the model's without the rotors, low-passed
    ("scale_u", 6),  # over SCALE_LP and that over SCALE_HP; the rotors' modelled rate change, the same
    ("scale_sums", 6),  # Σ y u, then Σ u u, per axis, over the scale's memory
    ("scale_clamped", 3),  # per axis 1 once the scale reached its clamp (1 ± SCALE_RANGE)
    ("alpha", 3),  # scratch of one step: the model's angular acceleration over the interval
    ("acc_cg", 3),  # and the accelerometer's reading moved to the centre of mass
    ("thrust", MAX_ROTORS),  # and each intact rotor's thrust at its speed over the interval (N)
    ("cmd", MAX_ROTORS),  # the speeds commanded over the interval that ends at the next step (rad/s)
    ("cmd_known", 1),  # 1 once commands were given (the speed test needs them)
    ("speed_low", MAX_ROTORS),  # the speed test's floor: the lowest speed a working motor can have (rad/s)
    ("s_speed", MAX_ROTORS),  # the speed test's sums
)
SCALE_LP = 0.02  # s: above the gyroscope's noise and the rotors' tone (chosen)
SCALE_HP = 1.0  # s: below the manoeuvres; what the model misses steadily (wind, trim) is left out (chosen)
SCALE_RANGE = 0.3  # the learnt scale stays within 1 ± this: the model within 30 %
SCALE_RATE = 0.03  # 1/s: the fastest it moves (a loss's moments before it is found move it 0.3 % in 0.1 s)
MODEL = layout(
    ("rotors", 1),
    ("mass", 1),
    ("inertia", 3),
    ("k_f", 1),
    ("k_z", 1),
    ("k_h", 1),
    ("tau", 1),
    ("omega_min", 1),
    ("omega_max", 1),
    ("omega_dot_max", 1),
    ("damping", 3),
    ("rot_drag", 3),
    ("g", 3 * MAX_ROTORS),  # per rotor: the moment per unit thrust
    ("ip_s", MAX_ROTORS),  # per rotor: its inertia times its sense, I_p s_i (the rotors' momentum per speed)
    ("body_drag", 2),  # the body's quadratic drag along x and y
    ("imu", 3),  # the accelerometer's position from the centre of mass (body, m)
    ("drag_moment", 4),  # roll's, then pitch's angular acceleration per specific force along x and y (rad/m)
)
DIAGNOSTICS = layout(
    ("eta", MAX_ROTORS),  # each rotor's effectiveness
    ("lost_sum", 1),  # the tests' statistics: the largest 'lost' sum and its rotor,
    ("lost_rotor", 1),
    ("damaged_sum", 1),  # the largest 'damaged' sum and its rotor
    ("damaged_rotor", 1),
    ("speed_sum", 1),  # the largest speed test's sum and its rotor
    ("speed_rotor", 1),
)
"""A step's diagnostics (``diag``): each rotor's effectiveness, then the tests' statistics (the
speed test's zero without measured speeds and commands)."""
DIAG = DIAGNOSTICS.end
STAT = DIAGNOSTICS.lost_sum
STATISTICS = DIAG - STAT
"""How many statistics a step reports, from ``diag[STAT]`` on (``Detection.statistics``' columns)."""
