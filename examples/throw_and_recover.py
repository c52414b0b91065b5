"""Throw the vehicle tumbling and let the recovery paper's bank of EKFs find gravity in flight.

python examples/throw_and_recover.py
"""

from quadest.flight import fly

flight = fly("throw", estimator="recovery", duration=6.0, seed=4)
s = flight.summary
print(f"released at {s['release_speed_m_s']:.1f} m/s tumbling at {s['release_rate_rad_s']:.1f} rad/s")
print(f"throw detected {s['detected_s']:.3f} s after the release, the bank converged {s['convergence_s']:.3f} s after")
print(f"gravity direction off by {s['gravity_error_at_handover_deg']:.1f}° at the handover")
print(f"upright {s['upright_s']:.2f} s after the release")
print(f"{s['status']}, tilted {s['final_tilt_deg']:.1f}° at the end")
