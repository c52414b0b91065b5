"""`quadest data`: datasets fetched from a local HTTP server on 127.0.0.1 that serves
small files laid out like the real sources: fetch, a checksum that differs (refused, nothing
half-written left), a download that breaks off (resumed with a range request), a dataset that is
not there (one line saying how to get it). No test reaches outside the machine."""

import hashlib
import random
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from quadest.cli.main import main
from quadest.errors import UsageError
from quadest.readers import catalog as C

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data"


class Server:
    """Serves ``files`` (path → bytes); ``cut`` (path → n) sends only the first n bytes of a
    file and drops the connection; every request's path and Range header are kept."""

    def __init__(self):
        self.files, self.cut, self.requests = {}, {}, []
        self.behave = {}  # path -> a function of the handler that answers instead
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):
                pass

            def do_GET(self):
                server.requests.append((self.path, self.headers.get("Range")))
                if self.path in server.behave:
                    server.behave[self.path](self)
                    return
                body = server.files.get(self.path)
                if body is None:
                    self.send_error(404)
                    return
                start = 0
                m = re.fullmatch(r"bytes=(\d+)-", self.headers.get("Range") or "")
                if m and int(m.group(1)) < len(body):
                    start = int(m.group(1))
                    self.send_response(206)
                    self.send_header("Content-Range", f"bytes {start}-{len(body) - 1}/{len(body)}")
                else:
                    self.send_response(200)
                self.send_header("Content-Length", str(len(body) - start))
                self.end_headers()
                n = server.cut.pop(self.path, None)
                self.wfile.write(body[start:] if n is None else body[start : start + n])
                if n is not None:
                    self.wfile.flush()
                    self.close_connection = True

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()


@pytest.fixture
def server():
    s = Server()
    yield s
    s.httpd.shutdown()


def _toy(server, files):
    """A dataset of trials like BROAD's, served by ``server``."""
    out = []
    for path, body in files.items():
        server.files[f"/repo/commit/{path}"] = body
        out.append(C.DataFile(path, f"{server.url}/repo/commit/{path}", hashlib.sha256(body).hexdigest(), len(body)))
    return C.Dataset(
        "toy", "a toy dataset", "nobody, 2026", "CC0", "bytes", f"{server.url}/repo", files=tuple(out), trials=True
    )


_RNG = random.Random(7)
FILES = {
    "01_slow_A.hdf5": _RNG.randbytes(300_000),
    "02_fast_B.hdf5": _RNG.randbytes(200_000),
    "trials.json": b'{"trials": {}}',
}


def test_fetch_checks_and_keeps(server, tmp_path):
    cat = {"toy": _toy(server, FILES)}
    folder = C.fetch("toy", root=tmp_path, catalog=cat, progress=False)
    assert folder == tmp_path / "toy"
    for path, body in FILES.items():
        assert (folder / path).read_bytes() == body
    n = len(server.requests)
    C.fetch("toy", root=tmp_path, catalog=cat, progress=False)  # already there, hashes right: nothing downloaded
    assert len(server.requests) == n
    assert not list((tmp_path / ".partial").glob("*"))


def test_only_the_chosen_trials(server, tmp_path):
    cat = {"toy": _toy(server, FILES)}
    C.fetch("toy", root=tmp_path, catalog=cat, trials=["02"], progress=False)
    assert sorted(p.name for p in (tmp_path / "toy").iterdir()) == ["02_fast_B.hdf5", "trials.json"]
    with pytest.raises(UsageError, match="no trial '7'"):
        C.fetch("toy", root=tmp_path, catalog=cat, trials=["7"], progress=False)


def test_a_checksum_that_differs_is_refused_and_nothing_is_kept(server, tmp_path):
    cat = {"toy": _toy(server, FILES)}
    body = FILES["02_fast_B.hdf5"]
    server.files["/repo/commit/02_fast_B.hdf5"] = bytes([body[0] ^ 0xFF]) + body[1:]  # the source changed
    with pytest.raises(ValueError, match="differs from the known"):
        C.fetch("toy", root=tmp_path, catalog=cat, trials=["02"], progress=False)
    assert not (tmp_path / "toy" / "02_fast_B.hdf5").exists()
    kept = ("trials.json", C.INCOMPLETE)  # the mark of a fetch that did not finish stays
    left = [p for p in (tmp_path / "toy").iterdir() if p.name not in kept] if (tmp_path / "toy").exists() else []
    assert left == [] and not list((tmp_path / ".partial").glob("*"))


def test_a_download_that_breaks_off_is_resumed(server, tmp_path):
    cat = {"toy": _toy(server, FILES)}
    server.cut["/repo/commit/01_slow_A.hdf5"] = 120_000
    with pytest.raises(ConnectionError, match="broke off after 120000 of 300000 bytes"):
        C.fetch("toy", root=tmp_path, catalog=cat, trials=["01"], progress=False)
    assert not (tmp_path / "toy" / "01_slow_A.hdf5").exists()
    parts = list((tmp_path / ".partial").glob("*.part"))
    assert len(parts) == 1 and parts[0].stat().st_size == 120_000
    C.fetch("toy", root=tmp_path, catalog=cat, trials=["01"], progress=False)
    assert (tmp_path / "toy" / "01_slow_A.hdf5").read_bytes() == FILES["01_slow_A.hdf5"]
    assert ("/repo/commit/01_slow_A.hdf5", "bytes=120000-") in server.requests
    assert not list((tmp_path / ".partial").glob("*"))


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_the_command_line(server, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(C.DATASETS, "toy", _toy(server, FILES))
    monkeypatch.setenv("QUADEST_DATA", str(tmp_path / "cache"))
    code, text, _ = run(capsys, "data", "list")
    assert code == 0 and all(name in text for name in ("broad", "blackbird_clover", "dido", "repoimu", "px4_ulog"))
    assert "CC BY 4.0" in text and "how to get it" in text
    code, text, _ = run(capsys, "data", "path", "toy")
    assert code == 1 and "quadest data fetch toy" in text
    code, text, _ = run(capsys, "data", "fetch", "toy", "--trials", "01")
    assert code == 0 and text.strip().splitlines()[-1] == str(tmp_path / "cache" / "toy")
    code, text, _ = run(capsys, "data", "path", "toy")
    assert code == 0 and text.strip() == str(tmp_path / "cache" / "toy")
    # refused in one line: a dataset quadest does not fetch, an unknown one, a missing one behind --data
    for argv, match in (
        (("data", "fetch", "dido"), "not fetched by quadest"),
        (("data", "fetch", "nope"), "unknown dataset"),
        (("benchmark", "broad", "--data", "broad"), "quadest data fetch broad"),
        (("benchmark", "flights", "--data", "all"), "quadest data fetch blackbird_clover"),
    ):
        code, _, err = run(capsys, *argv)
        assert code != 0 and match in err and len(err.strip().splitlines()) == 1, (argv, err)


def test_data_resolves_names_and_paths(tmp_path):
    assert C.resolve_data(str(tmp_path)) == tmp_path
    with pytest.raises(UsageError, match="quadest data fetch broad"):
        C.resolve_data("broad", root=tmp_path)
    (tmp_path / "broad").mkdir()
    (tmp_path / "broad" / "trials.json").write_text("{}")
    assert C.resolve_data("broad", root=tmp_path) == tmp_path / "broad"
    assert C.resolve_data("all", root=tmp_path) == tmp_path
    with pytest.raises(UsageError, match="not a dataset"):
        C.resolve_data("nowhere", root=tmp_path)


def test_the_catalog_pins_its_sources():
    """Every fetched file comes from an https address pinned to a commit, with a SHA-256 and a
    size; where ../shared/data has the same files (the copies the benchmarks ran on), their
    hashes are those."""
    for d in C.DATASETS.values():
        assert d.fetchable or d.instructions, d.name
        for f in d.files:
            assert f.url.startswith("https://") and re.search(r"/[0-9a-f]{40}/", f.url), f.url
            assert re.fullmatch(r"[0-9a-f]{64}", f.sha256) and f.size > 0
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} is absent: the hashes are checked against the shared copies only where they are")
    checked = 0
    for d in C.DATASETS.values():
        for f in d.files:
            local = SHARED / d.name / f.path
            if local.is_file():
                assert hashlib.sha256(local.read_bytes()).hexdigest() == f.sha256 and local.stat().st_size == f.size
                checked += 1
    assert checked >= 17


# -- answers that running again would not mend, and downloads held within bounds -----------------------
def _status(code):
    def answer(h):
        h.send_error(code)

    return answer


def _redirect_to_itself(h):
    h.send_response(302)
    h.send_header("Location", h.path)
    h.send_header("Content-Length", "0")
    h.end_headers()


@pytest.mark.parametrize(
    "answer, said",
    [
        (_status(404), "not found on the server (HTTP 404)"),
        (_status(500), "the server failed to answer (HTTP 500"),
        (_redirect_to_itself, "redirects in a loop (HTTP 302)"),
    ],
)
def test_an_http_error_is_named_not_called_a_break(server, tmp_path, answer, said):
    cat = {"toy": _toy(server, FILES)}
    server.behave["/repo/commit/02_fast_B.hdf5"] = answer
    with pytest.raises(C.DownloadRefused, match=re.escape(said)) as e:
        C.fetch("toy", root=tmp_path, catalog=cat, trials=["02"], progress=False)
    assert "resume" not in str(e.value) and "broke off" not in str(e.value)


def test_a_body_larger_than_the_catalogue_says_is_cut_and_refused(server, tmp_path):
    """A server that sends 5 MB for a 200 kB file, with or without saying so beforehand: quadest
    stops at the catalogue's size and keeps nothing."""
    cat = {"toy": _toy(server, FILES)}
    huge = b"x" * 5_000_000

    def without_length(h):
        h.send_response(200)
        h.end_headers()
        h.wfile.write(huge)
        h.close_connection = True

    for answer in (None, without_length):
        if answer is None:
            server.files["/repo/commit/02_fast_B.hdf5"] = huge  # states its Content-Length
        else:
            server.behave["/repo/commit/02_fast_B.hdf5"] = answer
        with pytest.raises(C.DownloadRefused, match="more than the file's 200000 bytes"):
            C.fetch("toy", root=tmp_path, catalog=cat, trials=["02"], progress=False)
        assert not list((tmp_path / ".partial").glob("*.part"))
        assert not (tmp_path / "toy" / "02_fast_B.hdf5").exists()


def test_a_server_that_trickles_meets_an_overall_deadline(server, tmp_path, monkeypatch):
    """A byte every 0.1 s never trips a per-read timeout; the file's overall deadline ends it,
    and what arrived is kept for the next fetch."""
    import time

    cat = {"toy": _toy(server, FILES)}

    def trickle(h):
        h.send_response(200)
        h.send_header("Content-Length", str(len(FILES["02_fast_B.hdf5"])))
        h.end_headers()
        try:
            for b in FILES["02_fast_B.hdf5"][:100]:
                h.wfile.write(bytes([b]))
                h.wfile.flush()
                time.sleep(0.1)
        except OSError:
            pass

    server.behave["/repo/commit/02_fast_B.hdf5"] = trickle
    monkeypatch.setattr(C, "DEADLINE_BASE_S", 1.0)
    monkeypatch.setattr(C, "MIN_RATE", 1e12)  # the deadline: 1 s
    t0 = time.monotonic()
    with pytest.raises(C.DownloadRefused, match="took longer than its"):
        C.fetch("toy", root=tmp_path, catalog=cat, trials=["02"], progress=False)
    assert time.monotonic() - t0 < 3.0


def test_data_path_after_a_fetch_that_did_not_finish(server, tmp_path, monkeypatch, capsys):
    """A fetch killed (or broken off) after one file arrived leaves its mark: ``data path`` says
    the dataset is not there and how to finish it, until a fetch completes."""
    monkeypatch.setitem(C.DATASETS, "toy", _toy(server, FILES))
    monkeypatch.setenv("QUADEST_DATA", str(tmp_path))
    server.cut["/repo/commit/02_fast_B.hdf5"] = 1000
    code, _, err = run(capsys, "data", "fetch", "toy")
    assert code == 1 and "broke off" in err
    assert (tmp_path / "toy" / "01_slow_A.hdf5").is_file()  # one file whole, the other not
    code, text, _ = run(capsys, "data", "path", "toy")
    assert code == 1 and "did not finish" in text and "quadest data fetch toy" in text
    with pytest.raises(UsageError, match="did not finish"):
        C.resolve_data("toy", root=tmp_path)
    code, _, _ = run(capsys, "data", "fetch", "toy")
    assert code == 0
    code, text, _ = run(capsys, "data", "path", "toy")
    assert code == 0 and text.strip() == str(tmp_path / "toy")
