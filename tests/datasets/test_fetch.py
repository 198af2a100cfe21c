"""fetch: downloads from a local HTTP server (never the internet), verified, atomic, resumable."""

from __future__ import annotations

import contextlib
import re
import threading
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest

from uwbwb.datasets import manifest as mf
from uwbwb.datasets.fetch import ChecksumError, FetchError, FetchReport, fetch, file_url

NAME = "toy-uwb"
BIG = "ranges/run 1.csv"  # a space: URLs must be percent-encoded


def _synthetic_files() -> dict[str, bytes]:
    rng = np.random.default_rng(7)
    t_s = np.arange(4000) * 0.01
    ranges = rng.uniform(0.5, 9.0, size=(4000, 4)).round(3)
    body = "\n".join(",".join([f"{t:.2f}", *map(str, r)]) for t, r in zip(t_s, ranges))
    return {
        "README.md": b"# toy UWB dataset\n",
        "LICENSE": b"MIT\n",
        BIG: ("t_s,r0,r1,r2,r3\n" + body + "\n").encode(),
        "ranges/empty.csv": b"",
        "anchors.yaml": b"x: [0, 1, 1, 0]\ny: [0, 0, 1, 1]\n",
    }


class _Handler(BaseHTTPRequestHandler):
    """GET with single ``bytes=N-`` ranges, plus switches to misbehave (see ``_Server``)."""

    protocol_version = "HTTP/1.1"

    def do_GET(self):
        srv: _Server = self.server
        rel = urllib.parse.unquote(urllib.parse.urlsplit(self.path).path).removeprefix("/base/")
        range_header = self.headers.get("Range")
        with srv.lock:
            srv.requests.append((rel, range_header))
        if rel not in srv.files or rel in srv.not_found:
            self._send(404, b"not found")
            return
        data = srv.files[rel]
        if rel in srv.corrupt:
            data = bytes([data[0] ^ 0xFF]) + data[1:]
        if rel in srv.oversize:
            data = data + b"extra\n"
        start, status = 0, 200
        if range_header and srv.honour_range:
            match = re.fullmatch(r"bytes=(\d+)-", range_header)
            start = int(match.group(1))
            if start >= len(data):
                self._send(416, b"", {"Content-Range": f"bytes */{len(data)}"})
                return
            status = 206
        body = data[start:]
        headers = {"Content-Range": f"bytes {start}-{len(data) - 1}/{len(data)}"} if status == 206 else {}
        drop_at = None
        with srv.lock:
            if srv.drops_left.get(rel, 0) > 0:
                srv.drops_left[rel] -= 1
                drop_at = len(body) // 3
        if drop_at is None:
            self._send(status, body, headers)
            return
        # Announce the full length, send a third, then hang up.
        self._send(status, body[:drop_at], headers, content_length=len(body))
        self.close_connection = True

    def _send(self, status, body, headers=None, content_length=None):
        self.send_response(status)
        self.send_header("Content-Length", str(len(body) if content_length is None else content_length))
        for key, value in (headers or {}).items():
            self.send_header(key, value)
        self.end_headers()
        self.wfile.write(body)
        self.wfile.flush()

    def log_message(self, format, *args):  # keep test output clean
        pass


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, files):
        super().__init__(("127.0.0.1", 0), _Handler)
        self.files = files
        self.lock = threading.Lock()
        self.requests: list[tuple[str, str | None]] = []
        self.not_found: set[str] = set()
        self.corrupt: set[str] = set()
        self.oversize: set[str] = set()
        self.drops_left: dict[str, int] = {}
        self.honour_range = True

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}/base/"

    def requests_for(self, rel):
        return [r for path, r in self.requests if path == rel]


@pytest.fixture(scope="module")
def files():
    return _synthetic_files()


@pytest.fixture(scope="module")
def manifest_csv(files, tmp_path_factory):
    src = tmp_path_factory.mktemp("published")
    for rel, data in files.items():
        (src / NAME / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / NAME / rel).write_bytes(data)
    out = src / "manifest.csv"
    mf.scan(src / NAME, NAME).to_csv(out, index=False)
    return out


@contextlib.contextmanager
def serving(files):
    """A :class:`_Server` for ``files`` on 127.0.0.1, running in a thread; shut down on exit."""
    srv = _Server(files)
    thread = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        yield srv
    finally:
        srv.shutdown()
        srv.server_close()
        thread.join(timeout=5)


@pytest.fixture
def server(files):
    with serving(files) as srv:
        yield srv


@pytest.fixture
def get(server, manifest_csv, tmp_path):
    """``fetch`` of the toy dataset from the local server into ``tmp_path``."""
    def run(**kwargs):
        kwargs = {"manifest": manifest_csv, "base_url": server.base_url, "timeout_s": 5, "progress": False,
                  **kwargs}
        return fetch(NAME, tmp_path, **kwargs)
    return run


def _leftovers(root):
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*.part"))


def test_fetch_downloads_and_verifies_every_file(get, files, tmp_path, manifest_csv, server):
    report = get()
    root = tmp_path / NAME
    assert isinstance(report, FetchReport) and report.root == root
    assert len(report.downloaded) + len(report.skipped) == report.n_files
    assert sorted(report.downloaded) == sorted(files) and not report.skipped and not report.resumed
    assert report.bytes_downloaded == sum(map(len, files.values()))
    for rel, data in files.items():
        assert (root / rel).read_bytes() == data
    assert _leftovers(root) == []
    assert (mf.verify(NAME, root, manifest=manifest_csv)["status"] == "ok").all()
    assert all(r is None for _, r in server.requests)  # nothing to resume, so no Range requests
    assert "5 file(s) downloaded" in str(report)


def test_fetch_skips_files_already_correct(get, files, tmp_path, server):
    get()
    n_requests = len(server.requests)
    again = get()
    assert len(server.requests) == n_requests  # nothing asked of the server
    assert sorted(again.skipped) == sorted(files) and not again.downloaded
    (tmp_path / NAME / "LICENSE").write_bytes(b"GPL\n")  # a wrong local file is replaced
    third = get()
    assert third.downloaded == ("LICENSE",) and len(third.skipped) == len(files) - 1
    assert (tmp_path / NAME / "LICENSE").read_bytes() == files["LICENSE"]


def test_dropped_connection_is_resumed_with_a_range_request(get, files, tmp_path, server):
    server.drops_left[BIG] = 1
    report = get()
    assert (tmp_path / NAME / BIG).read_bytes() == files[BIG]
    first, second = server.requests_for(BIG)
    assert first is None
    assert second == f"bytes={len(files[BIG]) // 3}-"
    assert report.resumed == (BIG,)
    assert report.bytes_downloaded == sum(map(len, files.values()))  # nothing fetched twice
    assert _leftovers(tmp_path / NAME) == []


def test_interrupted_fetch_keeps_only_a_part_file_and_the_next_call_resumes(get, files, tmp_path, server):
    server.drops_left[BIG] = 1
    with pytest.raises(FetchError, match=re.escape(BIG)) as info:
        get(retries=0)
    root = tmp_path / NAME
    assert info.value.url == file_url(server.base_url, BIG) and "run%201.csv" in info.value.url
    assert "resumes" in str(info.value)
    assert not (root / BIG).exists()
    assert (root / (BIG + ".part")).stat().st_size == len(files[BIG]) // 3
    report = get()
    assert (root / BIG).read_bytes() == files[BIG] and report.resumed == (BIG,)
    assert server.requests_for(BIG)[-1] == f"bytes={len(files[BIG]) // 3}-"
    assert _leftovers(root) == []


def test_server_ignoring_range_restarts_the_file_cleanly(get, files, tmp_path, server):
    server.honour_range = False
    part = tmp_path / NAME / (BIG + ".part")
    part.parent.mkdir(parents=True)
    stale = b"stale bytes from another version of the file"
    part.write_bytes(stale)
    report = get()
    assert (tmp_path / NAME / BIG).read_bytes() == files[BIG]
    assert server.requests_for(BIG) == [f"bytes={len(stale)}-"]  # asked to resume, got the whole file
    assert BIG not in report.resumed and not part.exists()


def test_bad_partial_data_is_discarded_and_downloaded_again(get, files, tmp_path, server):
    part = tmp_path / NAME / (BIG + ".part")
    part.parent.mkdir(parents=True)
    part.write_bytes(b"X" * 100)  # right length for a prefix, wrong bytes
    report = get()
    assert (tmp_path / NAME / BIG).read_bytes() == files[BIG]
    assert server.requests_for(BIG) == ["bytes=100-", None]
    assert BIG not in report.resumed


def test_corrupted_download_raises_and_leaves_no_file(get, tmp_path, server):
    server.corrupt.add(BIG)
    with pytest.raises(ChecksumError, match=r"SHA-256 .* deleted") as info:
        get()
    root = tmp_path / NAME
    assert info.value.path == BIG and info.value.url == file_url(server.base_url, BIG)
    assert BIG in str(info.value) and info.value.url in str(info.value)
    assert not (root / BIG).exists() and _leftovers(root) == []
    assert info.value.report is not None and len(info.value.report.downloaded) < info.value.report.n_files


def test_oversized_download_raises_and_leaves_no_file(get, tmp_path, server):
    server.oversize.add("LICENSE")
    with pytest.raises(ChecksumError, match="more than the 4 bytes"):
        get()
    assert not (tmp_path / NAME / "LICENSE").exists() and _leftovers(tmp_path / NAME) == []


def test_http_404_names_file_and_url(get, tmp_path, server):
    server.not_found.add("anchors.yaml")
    with pytest.raises(FetchError, match=r"anchors\.yaml: HTTP 404") as info:
        get()
    assert info.value.url in str(info.value) and info.value.url.endswith("/base/anchors.yaml")
    assert not (tmp_path / NAME / "anchors.yaml").exists()
    assert server.requests_for("anchors.yaml") == [None]  # an HTTP error is not retried


def test_unreachable_server_is_a_fetch_error(manifest_csv, tmp_path):
    with _Server({}) as dead:  # bind a port, then close it: nothing listens there
        base_url = dead.base_url
    with pytest.raises(FetchError, match="failed after 2 attempt"):
        fetch(NAME, tmp_path, manifest=manifest_csv, base_url=base_url, retries=1, timeout_s=2, progress=False)


def test_bad_arguments(manifest_csv, tmp_path):
    with pytest.raises(ValueError, match="unknown dataset 'nope'"):
        fetch("nope", tmp_path, manifest=manifest_csv, base_url="http://127.0.0.1:9/", progress=False)
    with pytest.raises(ValueError, match="not a URL"):
        fetch(NAME, tmp_path, manifest=manifest_csv, base_url="127.0.0.1/base", progress=False)
    with pytest.raises(ValueError, match="no base URL known"):
        fetch(NAME, tmp_path, manifest=manifest_csv, progress=False)


def test_committed_manifest_urls_are_built_from_datasets_json():
    infos = mf.load_datasets_info()
    url = file_url(infos["hanyang-outdoor-uwb"].base_url, "Static_measurements/LOS/height_50.0cm/2m.csv")
    assert url == ("https://raw.githubusercontent.com/cucudasluv/UWB-dataset/HEAD/"
                   "Static_measurements/LOS/height_50.0cm/2m.csv")
