"""The unit checks go through a long recording block by block (data.checks.BLOCK): the same
results whatever the block, so a 10⁷-row file is checked in a few MB beside its own arrays."""

import numpy as np
import pytest

import quadest.data.checks as checks
from quadest.cli.recordings import attitude_blocks
from quadest.rotation import quat_to_euler
from quadest.sim import simulate


@pytest.fixture(scope="module")
def recs():
    six = simulate("six-position", "bebop2", seed=3, duration=40.0)
    flight = simulate("nominal", "bebop2", seed=3, duration=30.0)
    mag = flight.mag.copy()
    mag[::7] = np.nan  # rows without a magnetometer sample
    return six, flight, mag


def _all(recs):
    six, flight, mag = recs
    return (
        checks.turn_scale(flight.t, flight.gyr, mag, offset=True),
        checks.turn_scale(flight.t, flight.gyr, mag, offset=False),
        checks.rests(six.t, six.acc),
        checks.still_rate_across_gravity(six.t, six.gyr, six.acc),
        checks.tilt_disagreement(flight.true_q, flight.acc),
    )


@pytest.mark.parametrize("block", [37, 1000])
def test_the_checks_do_not_depend_on_the_block(recs, block, monkeypatch):
    whole = _all(recs)
    monkeypatch.setattr(checks, "BLOCK", block)
    parts = _all(recs)
    for a, b in zip(whole[:2], parts[:2], strict=True):  # sums in another order: rounding only
        assert np.allclose(a, b, rtol=1e-12, atol=0)
    assert parts[2] == whole[2] and len(whole[2]) == 5  # the six positions' rests, not one lost at an edge
    assert parts[3] == whole[3] and parts[4] == whole[4]


def test_the_attitude_columns_are_the_euler_angles_of_the_estimate(recs):
    flight = recs[1]
    blocks = list(attitude_blocks(flight.t, flight.true_q, {"extra": flight.gyr[:, 0]}, rows=333))
    cols = {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}
    assert len(blocks) == -(-len(flight.t) // 333)
    assert np.array_equal(np.column_stack([cols["roll"], cols["pitch"], cols["yaw"]]), quat_to_euler(flight.true_q))
    assert np.array_equal(np.column_stack([cols[f"q_{c}"] for c in "wxyz"]), flight.true_q)
    assert np.array_equal(cols["t"], flight.t) and np.array_equal(cols["extra"], flight.gyr[:, 0])


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_table_written_in_blocks_is_the_table_written_whole(tmp_path, suffix):
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    from quadest.data import write_blocks, write_table

    rng = np.random.default_rng(1)
    cols = {"t": np.arange(1000) / 100.0, "a": rng.normal(size=1000), "b": rng.normal(size=1000)}
    blocks = ({k: v[s : s + 333] for k, v in cols.items()} for s in range(0, 1000, 333))
    whole, parts = tmp_path / f"whole{suffix}", tmp_path / f"parts{suffix}"
    write_table(cols, whole)
    write_blocks(blocks, parts)
    read = pq.read_table if suffix == ".parquet" else pcsv.read_csv
    assert read(parts).equals(read(whole)) and read(parts).num_rows == 1000
    if suffix == ".csv":
        assert parts.read_text().splitlines()[0] == "t,a,b" and parts.read_bytes() == whole.read_bytes()
    with pytest.raises(ValueError, match="no rows"):
        write_blocks(iter(()), tmp_path / f"empty{suffix}")
    assert not (tmp_path / f"empty{suffix}").exists()


def test_sensors_only_keeps_the_samples_and_drops_the_truth(recs):
    flight = recs[1]
    sensors = flight.sensors_only()
    assert sensors.truth == [] and flight.truth  # the original keeps its truth
    for name in ("t", "gyr", "acc", "mag"):
        assert getattr(sensors, name) is getattr(flight, name)  # not copied
    assert sensors.meta == flight.meta
