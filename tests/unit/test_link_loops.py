"""A link that loops, as an input, an output or an output folder: one line naming it, on every
command (quadest.data.files.same_file, output_target, output_folder; readers.detect_format)."""

import pytest

from quadest.cli.main import main
from quadest.data import save_recording
from quadest.sim import simulate


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("loops") / "x.csv"
    return save_recording(simulate("rest", "bebop2", seed=1, duration=1.0), path)


@pytest.mark.parametrize(
    "argv",
    [
        ["estimate", "LOOP", "-o", "OUT/e.csv"],
        ["info", "LOOP"],
        ["compare", "--recording", "LOOP"],
        ["estimate", "REC", "-o", "LOOP"],
        ["report", "REC", "-o", "LOOP"],
        ["calibrate", "gyro", "REC", "-o", "LOOP"],
        ["compare", "--recording", "REC", "--json", "LOOP"],
        ["fly", "-o", "LOOP", "--duration", "1"],
    ],
    ids=lambda a: " ".join(a),
)
def test_a_link_that_loops_is_one_line(argv, recording, tmp_path, capsys):
    """Before: ``internal error (RuntimeError: Symlink loop from ...)`` (pathlib's resolve) and,
    for fly's folder, ``[Errno 17] File exists``."""
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    names = {"LOOP": str(loop), "REC": str(recording), "OUT": str(tmp_path)}
    code = main([names.get(a, a.replace("OUT", str(tmp_path))) for a in argv])
    err = capsys.readouterr().err
    assert code in (1, 2) and len(err.strip().splitlines()) == 1, err
    assert "internal error" not in err and str(loop) in err and "Errno" not in err
