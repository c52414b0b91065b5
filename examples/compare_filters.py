"""Every quadest filter on one simulated flight, side by side (what ``quadest compare`` prints).

python examples/compare_filters.py
"""

from quadest.evaluation.runner import estimate, score
from quadest.filters import FILTERS
from quadest.sim import simulate

rec = simulate("nominal", seed=2, duration=20.0)  # normal flight with 3 m/s² manoeuvres
print(f"{'filter':12s} {'roll':>6s} {'pitch':>6s} {'yaw':>6s}   (RMS, degrees)")
for name in FILTERS:
    rms = score(rec, estimate(rec, name).q)["rms_deg"]
    print(f"{name:12s} {rms['roll']:6.2f} {rms['pitch']:6.2f} {rms['yaw']:6.2f}")
