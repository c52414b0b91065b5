"""Fly the vehicle through the loss of a rotor with an estimator in the loop.

The fault-tolerant controller takes over once the loss is known (after the flight's
``detect_delay_s``; the loss is told to it, not detected: an oracle, said in the summary's docs).

    python examples/fly_a_rotor_loss.py
"""

from quadest.flight import FlightParams, fly
from quadest.sim import Failure

flight = fly("rotor-loss", estimator="robust", duration=8.0, failure=Failure(rotor=0, time_s=2.0))
s = flight.summary
delay_ms = 1e3 * FlightParams().detect_delay_s
print(f"the loss is told to the controller {delay_ms:.0f} ms after it happens (an oracle: not detected yet)")
print(f"{s['status']}: spinning at {s['spin_rate_rad_s']:.1f} rad/s, tilted {s['tilt_deg']:.1f}°")
print(f"attitude error in the loop after the loss: {s['attitude_error_after_failure_rms_deg']:.2f}° RMS")
if s["position_rms_settled_m"] is None:  # the level relaxed hover wanders about a metre (docs/vehicle.md)
    print("did not settle within 0.3 m of the hover point in the flight")
else:
    print(f"position error once settled: {s['position_rms_settled_m']:.2f} m RMS")
