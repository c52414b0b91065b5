"""The public datasets quadest reads, where they come from, and how to get them
(``quadest data list | fetch | path``).

Each dataset's files are downloaded from where their authors publish them, pinned to a commit,
each checked against its SHA-256 (the hashes of the copies quadest's benchmarks were run on), into
a cache folder (``~/.cache/quadest/data``, or ``QUADEST_DATA``) in the layout the readers expect.
Downloads go through pooch (the file is moved into place only when its hash matches); a
download that breaks off keeps what arrived in ``<cache>/.partial`` and the next fetch resumes it
with an HTTP range request. A dataset without published terms for redistribution or without a
stable address is listed with instructions instead of fetched.
"""

from __future__ import annotations

import http.client
import os
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

from quadest.errors import UsageError
from quadest.extras import need
from quadest.progress import bar as progress_bar


@dataclass(frozen=True)
class DataFile:
    """One file: where it lands (relative to the dataset's folder), where it comes from, its
    SHA-256 and size in bytes."""

    path: str
    url: str
    sha256: str
    size: int


@dataclass(frozen=True)
class Dataset:
    name: str
    title: str
    publication: str
    terms: str
    contents: str
    source: str  # the page or repository the authors publish it at
    files: tuple = ()  # DataFile; empty: not fetched, see ``instructions``
    instructions: str = ""
    trials: bool = False  # its files are trials a user may choose (--trials)
    notes: tuple = field(default_factory=tuple)

    @property
    def fetchable(self) -> bool:
        return bool(self.files)

    @property
    def size(self) -> int:
        return sum(f.size for f in self.files)


_BROAD = "https://github.com/dlaidig/broad/raw/afbaa4d75c4cd7c8ca76b8145b1812312d87fb7f/"
_BROAD_TRIALS = (
    ("02_undisturbed_slow_rotation_B", "33ed3432ece89cfbd8c5c069a176106a05dad019302759353244c71d70d7e5f5", 3926925),
    (
        "05_undisturbed_slow_rotation_with_breaks_B",
        "d74cc90958fc05a9fc1a6d58465a62c75a61f205a75ea2e6207ef37d7b1c89a7",
        4073405,
    ),
    ("07_undisturbed_fast_rotation_B", "bff6444d38b836482040a328d6060741816ed0150cf2640db94550c6a796b3d8", 4080123),
    (
        "09_undisturbed_fast_rotation_with_breaks_B",
        "40a6e3e69805ba056a53362ca17e75199cc8873aa167b8cf783bb9f71d133f55",
        4075108,
    ),
    ("11_undisturbed_slow_translation_B", "ea4ecb8a27d040cecdfb97cdee45023ea461e065bfc402ce7fe6a7c9a0f325e0", 3710735),
    (
        "14_undisturbed_slow_translation_with_breaks_B",
        "a4e6d406a64350e4ea7f7352e39db794b7327d89dc4cd4e7c9caf10bb9c22ebe",
        3559034,
    ),
    ("16_undisturbed_fast_translation_B", "eebc009755c4fc53c49369a19bae942cf093342a13a51a1ca0eeb23b2cc74abc", 3994996),
    (
        "18_undisturbed_fast_translation_with_breaks_B",
        "1b81785ff4310cc33bb0ee24620f502ede7ca0c79f7f08ebcc9f240d26f7ac6e",
        3944680,
    ),
    ("25_disturbed_tapping_B", "d6d9b55c5c84821eaaae96d93cc857b852af24fcb7c93a5fa98b7e6c1e9cae5d", 3651796),
    ("27_disturbed_phone_vibration_B", "9041093636cd2c2e992651f4cd7f7f25c4b585971fd5d4821b020ca3c5d15dff", 3684968),
    ("31_disturbed_stationary_magnet_D", "b65d5da814f8fdd9e7a1ecea502888d1ffef472bd3e3605767293bdc65285ae1", 3925668),
    ("33_disturbed_attached_magnet_2cm", "b81855b453629e023635d966f77c87cd17b195c919888d725b57b1cca037962d", 3316402),
)
_BLACKBIRD = (
    "https://github.com/uzh-rpg/learned_inertial_model_odometry/raw/580ea06440bf59badc9c941b61a71cdf173d9131/"
    "datasets/Blackbird/clover/yawForward/maxSpeed5p0/"
)

DATASETS = {
    d.name: d
    for d in (
        Dataset(
            "broad",
            "BROAD, the Berlin Robust Orientation Estimation Assessment Dataset (12 of its 39 trials)",
            "D. Laidig, M. Caruso, A. Cereatti, T. Seel, Data 6(7), 2021, doi:10.3390/data6070072",
            "CC BY 4.0",
            "9-axis IMU at 286 Hz with optical motion-capture orientation; slow and fast rotation and "
            "translation, rest breaks, tapping, vibration, magnets",
            "https://github.com/dlaidig/broad",
            files=tuple(
                DataFile(f"{name}.hdf5", f"{_BROAD}data_hdf5/{name}.hdf5", h, n) for name, h, n in _BROAD_TRIALS
            )
            + (
                DataFile(
                    "trials.json",
                    f"{_BROAD}data_mat/trials.json",
                    "9f4a680062fd5b6b500653fe7f8e7dd774dedbf4fe573210328ec8d0d263c2fd",
                    12177,
                ),
            ),
            trials=True,
            notes=(
                "quadest's benchmark uses these 12 trials (docs/readers.md); the other 27 are in the same repository",
            ),
        ),
        Dataset(
            "blackbird_clover",
            "Blackbird UAV dataset, 'clover' at 5 m/s, train and val as prepared by UZH-RPG",
            "A. Antonini et al., ISER 2018 (Blackbird); G. Cioffi et al., RA-L 2023 (learned inertial model odometry)",
            "GPL-3.0 (the repository that prepared it)",
            "aggressive quadrotor flight, IMU at 100 Hz, Vicon pose and velocity",
            "https://github.com/uzh-rpg/learned_inertial_model_odometry",
            files=(
                DataFile(
                    "train/data.hdf5",
                    f"{_BLACKBIRD}train/data.hdf5",
                    "7df533a8ea854fa9963ad0162206702d9943a3d71f43ce15109cc4d6dccd26fc",
                    1899072,
                ),
                DataFile(
                    "train/stamped_groundtruth_imu.txt",
                    f"{_BLACKBIRD}train/stamped_groundtruth_imu.txt",
                    "0044a2e46ec937886193f84fd664aa9a36768aca4833e25a960947fb963a3363",
                    1617298,
                ),
                DataFile(
                    "val/data.hdf5",
                    f"{_BLACKBIRD}val/data.hdf5",
                    "27ff7bf6fa3169a2c1f52fb02e2a399bcbb6069ac3017beda2949aa2f0d02e7f",
                    630272,
                ),
                DataFile(
                    "val/stamped_groundtruth_imu.txt",
                    f"{_BLACKBIRD}val/stamped_groundtruth_imu.txt",
                    "535f1879ea9e09280efa428b032f7c41c80e7f8237f19dd2ad3693fe9aae051e",
                    533008,
                ),
            ),
        ),
        Dataset(
            "px4_ulog",
            "PX4's pyulog test log (sample.ulg)",
            "PX4 pyulog, test/sample.ulg",
            "BSD-3-Clause",
            "a real PX4 log, about 69 s moved by hand: raw IMU and magnetometer at about 250 Hz, the onboard EKF2 "
            "attitude as a reference",
            "https://github.com/PX4/pyulog",
            files=(
                DataFile(
                    "sample.ulg",
                    "https://github.com/PX4/pyulog/raw/6e74ac3a454f96a30fdb1c147b2a0d92fe380d4d/test/sample.ulg",
                    "81952e6059bc095717e7911c010e07f85749d6b04d332a5ffc51575a3fd0a558",
                    4053364,
                ),
            ),
        ),
        Dataset(
            "dido",
            "DIDO quadrotor flights",
            "K. Zhang et al., 'DIDO: Deep Inertial Quadrotor Dynamical Odometry', IEEE RA-L 2022, arXiv:2203.03149",
            "no license published: evaluation use only",
            "real quadrotor flights at 400 Hz with motion-capture pose, velocity and acceleration",
            "https://arxiv.org/abs/2203.03149",
            instructions="The authors publish no license and quadest knows no stable download address: get the flights "
            "from the address the paper gives, and put the HDF5 files (circle_*, eight_*, random_*) in "
            "<cache>/dido/ (quadest data path dido).",
        ),
        Dataset(
            "repoimu",
            "RepoIMU, T-stick and pendulum trials",
            "A. Szczęsna et al., 'Reference Data Set for Accuracy "
            "Evaluation of Orientation Estimation Algorithms for Inertial Motion Capture Systems', ICCVG 2016",
            "no license stated: evaluation use only",
            "9-axis IMU at 100 Hz with Vicon orientation",
            "the RepoIMU page of the Silesian University of Technology (named in the paper)",
            instructions="No license is stated and the files are offered from the authors' page only: download the "
            "T-stick and pendulum CSV files there and put them in <cache>/repoimu/TStick and "
            "<cache>/repoimu/Pendulum.",
        ),
        Dataset(
            "ardupilot",
            "An ArduCopter 4.1 DataFlash log (hover, intact propellers)",
            "a fault-tolerance study's log",
            "no license stated: evaluation use only",
            "IMU, MAG and ATT (onboard EKF3 attitude) messages",
            "not published at a stable address",
            instructions="quadest's tests read one such log; it has no public address. Any ArduPilot .BIN log of yours "
            "reads the same way (quadest info LOG.BIN).",
        ),
    )
}
"""The datasets by name (``quadest data list``)."""


def cache_dir(override=None) -> Path:
    """Where datasets are kept: ``override``, else ``QUADEST_DATA``, else ``~/.cache/quadest/data``."""
    if override:
        return Path(override).expanduser()
    env = os.environ.get("QUADEST_DATA")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "quadest" / "data"


def dataset(name: str, catalog=None) -> Dataset:
    catalog = DATASETS if catalog is None else catalog
    if name not in catalog:
        raise UsageError(f"unknown dataset {name!r}; datasets: {', '.join(catalog)} (quadest data list)")
    return catalog[name]


def select_files(d: Dataset, trials=None) -> list[DataFile]:
    """The dataset's files, or with ``trials`` (prefixes or names, for a dataset of trials) those
    trials and the files that are not trials (its index)."""
    if not trials:
        return list(d.files)
    if not d.trials:
        raise UsageError(f"dataset {d.name!r} has no trials to choose: leave out --trials")
    wanted, chosen = [t.strip() for t in trials if t.strip()], []
    for t in wanted:
        match = [f for f in d.files if f.path.endswith(".hdf5") and f.path.startswith(t)]
        if not match:
            names = ", ".join(f.path[:-5] for f in d.files if f.path.endswith(".hdf5"))
            raise UsageError(f"dataset {d.name!r} has no trial {t!r}; its trials: {names}")
        chosen += [f for f in match if f not in chosen]
    return chosen + [f for f in d.files if not f.path.endswith(".hdf5")]


INCOMPLETE = ".fetch-incomplete"
"""Written into a dataset's folder when a fetch starts and removed when it ends well: a fetch that
was killed or failed leaves it, and the dataset is not called present."""


def interrupted_fetch(d: Dataset, root=None) -> bool:
    """Whether the last fetch of ``d`` did not finish (killed, broken off or refused)."""
    return (cache_dir(root) / d.name / INCOMPLETE).exists()


def is_fetched(d: Dataset, root=None, trials=None) -> bool:
    folder = cache_dir(root) / d.name
    return (
        d.fetchable
        and not interrupted_fetch(d, root)
        and all((folder / f.path).is_file() for f in select_files(d, trials))
    )


def is_present(d: Dataset, root=None) -> bool:
    """Whether ``d``'s folder holds it: fetched whole, or put there by hand (any file), and no
    fetch of it left unfinished."""
    folder = cache_dir(root) / d.name
    return not interrupted_fetch(d, root) and folder.is_dir() and any(folder.iterdir())


def not_present_reason(d: Dataset, root=None) -> str:
    """How to get ``d`` into the cache, in a few words."""
    if interrupted_fetch(d, root):
        return f"its last fetch did not finish: quadest data fetch {d.name} completes it"
    return f"quadest data fetch {d.name}" if d.fetchable else d.instructions


def fetch(name: str, *, root=None, trials=None, progress: bool = True, catalog=None) -> Path:
    """Download dataset ``name`` (or the chosen ``trials``) into ``<root>/<name>``; files already
    there with the right hash are kept. Returns the dataset's folder. Raises UsageError for a
    dataset that is not fetched (its instructions), ValueError for a file whose hash differs
    (nothing of it is kept), ConnectionError when a download breaks off (what arrived is kept
    and resumed by the next call)."""
    d = dataset(name, catalog)
    if not d.fetchable:
        raise UsageError(f"dataset {name!r} is not fetched by quadest: {d.instructions}")
    folder = cache_dir(root) / d.name
    partial = cache_dir(root) / ".partial"
    pooch = need("pooch", "quadest data fetch")
    pooch.get_logger().setLevel("WARNING")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / INCOMPLETE).write_text("a fetch started and has not finished\n")
    for f in select_files(d, trials):
        target = folder / f.path
        try:
            pooch.retrieve(
                f.url,
                known_hash=f"sha256:{f.sha256}",
                fname=target.name,
                path=target.parent,
                downloader=ResumingDownloader(partial, f, progress, d.source),
            )
        except ValueError as e:
            if "hash" not in str(e).lower():
                raise
            raise ValueError(
                f"{f.url}: its SHA-256 differs from the known {f.sha256[:12]}…: refused, nothing of it "
                f"was kept (the source may have changed; the dataset's page: {d.source})"
            ) from None
    (folder / INCOMPLETE).unlink()
    return folder


DEADLINE_BASE_S = 120.0
MIN_RATE = 20_000
"""A file's download must end within ``DEADLINE_BASE_S + size / MIN_RATE`` seconds (BROAD's
4 MB trials: 320 s); each read waits at most ``READ_TIMEOUT_S``."""
READ_TIMEOUT_S = 60.0


def http_refusal(url: str, e: urllib.error.HTTPError, page: str) -> str:
    """What an HTTP error status means for a download, in one line (not a resumable break)."""
    if 300 <= e.code < 400:
        return f"{url}: the server redirects in a loop (HTTP {e.code}): the file has moved; see {page}"
    if e.code in (404, 410):
        return f"{url}: not found on the server (HTTP {e.code}): the file has moved or gone; see {page}"
    if e.code in (401, 403):
        return f"{url}: the server refuses access (HTTP {e.code}); see {page}"
    if e.code == 429 or e.code >= 500:
        return f"{url}: the server failed to answer (HTTP {e.code} {e.reason}): try again later"
    return f"{url}: the server answered HTTP {e.code} {e.reason}; see {page}"


class DownloadRefused(OSError):
    """A download that running again would not mend: an HTTP error status, a body larger than the
    catalogue's size, or one that takes longer than its deadline (resumable, said so)."""


class ResumingDownloader:
    """A pooch downloader that resumes: it appends to ``<partial>/<sha256>.part`` from where a
    broken-off download stopped (HTTP range request; a server that ignores the range starts it
    again), then hands the whole file to pooch, which checks its hash before moving it into place."""

    def __init__(self, partial: Path, f: DataFile, progress: bool, page: str = ""):
        self.partial, self.f, self.progress, self.page = partial, f, progress, page
        self.deadline = time.monotonic() + DEADLINE_BASE_S + f.size / MIN_RATE

    def _remaining(self, url: str, have: int) -> float:
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise DownloadRefused(
                f"{url}: the download took longer than its {DEADLINE_BASE_S + self.f.size / MIN_RATE:.0f} s "
                f"(after {have} of {self.f.size} bytes; the server is too slow): run the same command again "
                "to resume it"
            )
        return min(READ_TIMEOUT_S, left)

    def _too_large(self, url: str, n: int, part: Path) -> DownloadRefused:
        part.unlink(missing_ok=True)
        return DownloadRefused(
            f"{url}: the server sends more than the file's {self.f.size} bytes ({n} or more): refused, "
            f"nothing of it was kept (the source may have changed; see {self.page})"
        )

    def _copy(self, r, url: str, part: Path, start: int) -> None:
        """The body into ``part`` (appended from ``start``), never past the catalogue's size."""
        length = r.headers.get("Content-Length")
        if length is not None and length.isdigit() and start + int(length) > self.f.size:
            raise self._too_large(url, start + int(length), part)
        with (
            open(part, "ab" if start else "wb") as out,
            progress_bar(
                total=self.f.size,
                initial=start,
                unit="B",
                unit_scale=True,
                leave=False,
                desc=Path(self.f.path).name,
                disable=not self.progress,
            ) as bar,
        ):
            have = start
            while True:
                chunk = r.read1(1 << 16)  # what has arrived: a slow server meets the deadline below
                if not chunk:
                    break
                have += len(chunk)
                if have > self.f.size:
                    out.close()
                    raise self._too_large(url, have, part)
                out.write(chunk)
                bar.update(len(chunk))
                self._remaining(url, have)

    def __call__(self, url, output_file, pooch_obj, check_only=False):
        self.partial.mkdir(parents=True, exist_ok=True)
        part = self.partial / f"{self.f.sha256}.part"
        start = part.stat().st_size if part.is_file() else 0
        if start > self.f.size:  # not this file's beginning: start again
            part.unlink()
            start = 0
        if start < self.f.size:
            self._download(url, part, start)
        # the whole file goes to pooch, which checks its hash: a wrong one is deleted, not resumed
        os.replace(part, output_file)

    def _download(self, url: str, part: Path, start: int) -> None:
        headers = {"User-Agent": "quadest"}
        if start:
            headers["Range"] = f"bytes={start}-"
        try:
            request = urllib.request.Request(url, headers=headers)
            with urllib.request.urlopen(request, timeout=self._remaining(url, start)) as r:
                if start and r.status != 206:  # the server sends the whole file
                    start = 0
                self._copy(r, url, part, start)
        except DownloadRefused:
            raise
        except urllib.error.HTTPError as e:
            raise DownloadRefused(http_refusal(url, e, self.page)) from None
        except (urllib.error.URLError, OSError, http.client.HTTPException) as e:
            have = part.stat().st_size if part.is_file() else 0
            raise ConnectionError(
                f"{url}: the download broke off after {have} of {self.f.size} bytes ({e}); run "
                "the same command again to resume it"
            ) from None
        have = part.stat().st_size
        if have < self.f.size:
            raise ConnectionError(
                f"{url}: the download broke off after {have} of {self.f.size} bytes; run the same "
                "command again to resume it"
            )


def resolve_data(arg, root=None) -> Path:
    """A ``--data`` argument: an existing path as it is; a dataset name as its folder in the
    cache; ``all`` as the cache itself (every dataset fetched). Raises UsageError, saying how to
    fetch it, for a dataset not in the cache."""
    p = Path(arg)
    if p.exists():
        return p
    name = str(arg)
    if name == "all":
        c = cache_dir(root)
        if not c.is_dir():
            raise UsageError(f"no datasets in {c} yet: fetch them with quadest data fetch NAME (quadest data list)")
        return c
    if name in DATASETS:
        d = DATASETS[name]
        if is_present(d, root):
            return cache_dir(root) / name
        raise UsageError(f"dataset {name!r} is not in {cache_dir(root)}: {not_present_reason(d, root)}")
    raise UsageError(f"--data {arg}: no such file or folder, and not a dataset ({', '.join(DATASETS)}, or all)")
