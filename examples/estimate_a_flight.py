"""Estimate the attitude of a simulated rotor loss with quadest's own filter and score it.

python examples/estimate_a_flight.py
"""

from quadest.evaluation.runner import estimate, score
from quadest.sim import simulate

rec = simulate("damaged-rotor", seed=1, duration=10.0)  # a Bebop 2 losing half a rotor at 5 s
result = estimate(rec, "robust")  # any name of quadest.filters.FILTERS, or an installed peer
errors = score(rec, result.q, t_from=5.0)  # from the failure on
rms = errors["rms_deg"]
print(f"robust after the failure: roll {rms['roll']:.2f}°, pitch {rms['pitch']:.2f}°, yaw {rms['yaw']:.2f}° RMS")
