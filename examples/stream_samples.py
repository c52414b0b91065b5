"""Run an estimator sample by sample, as on a vehicle: ``update`` per IMU sample.

python examples/stream_samples.py
"""

import numpy as np

from quadest.filters import make_filter
from quadest.rotation import quat_to_euler
from quadest.sim import simulate

rec = simulate("hover", seed=3, duration=5.0)
est = make_filter("robust", declination=rec.declination)
dt = np.diff(rec.t, prepend=rec.t[0] - (rec.t[1] - rec.t[0]))
for k in range(len(rec.t)):
    q = est.update(rec.gyr[k], rec.acc[k], None if rec.mag is None else rec.mag[k], dt=dt[k])
est_deg, true_deg = np.degrees(quat_to_euler(q)), np.degrees(quat_to_euler(rec.true_q[-1]))
print(
    f"after {rec.t[-1]:.1f} s (estimate / truth): "
    + ", ".join(f"{axis} {e:.2f}° / {t:.2f}°" for axis, e, t in zip(("roll", "pitch", "yaw"), est_deg, true_deg))
)
