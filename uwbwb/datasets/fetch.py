"""Download a public dataset from upstream, checked file by file against the manifest.

``python -m uwbwb fetch NAME`` (or :func:`fetch`) downloads every file of
dataset ``NAME`` listed in ``data/manifest.csv`` that is missing or wrong under
``data/external/NAME/``. Each file is

* streamed to ``<file>.part`` and moved to its final name (``os.replace``) only
  after its size and SHA-256 match the manifest, so a final name never holds
  partial or unverified data;
* resumed when a ``.part`` is left from an interrupted run (HTTP ``Range``
  request; a server that ignores ``Range`` gets a clean restart);
* skipped when it is already present and correct.

The URL of a file is the dataset's ``base_url`` (``data/datasets.json``, or the
``base_url`` argument) followed by its manifest path. The base URLs point at the
upstream repositories' raw files and are unverified from the machine that built
the manifest; the checksums are those of the published copies the project was
tested against, so any difference is reported, never accepted.

Only :mod:`urllib` is used.
"""

from __future__ import annotations

import http.client
import os
import re
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from .. import __version__
from .discovery import EXTERNAL_DIR
from .manifest import PART_SUFFIX, dataset_files, file_status, load_datasets_info, sha256_file

_CHUNK_BYTES = 1 << 16
_USER_AGENT = f"uwbwb/{__version__} (dataset fetch; urllib)"
_CONTENT_RANGE_RE = re.compile(r"bytes\s+(\d+)-(\d+)/(\d+|\*)")


class FetchError(RuntimeError):
    """A file could not be downloaded or did not match the manifest.

    Attributes
    ----------
    path
        Manifest path of the file (relative to the dataset root).
    url
        URL it was requested from.
    report
        What had been done before the failure (a :class:`FetchReport`), when known.
    """

    def __init__(self, message: str, *, path: str, url: str):
        super().__init__(message)
        self.path = path
        self.url = url
        self.report: FetchReport | None = None


class ChecksumError(FetchError):
    """Downloaded bytes differ from the manifest (size or SHA-256); the bad data was deleted."""


class _Interrupted(Exception):
    """The transfer stopped early; the ``.part`` file may be resumed."""


@dataclass(frozen=True)
class FetchReport:
    """Outcome of :func:`fetch`.

    Attributes
    ----------
    dataset
        Dataset name.
    root
        Dataset root the files were written to.
    n_files
        Number of files the manifest lists for the dataset.
    downloaded
        Manifest paths written by this call (in manifest order).
    resumed
        Those of ``downloaded`` completed by continuing partial data (a ``.part``
        left by an earlier run, or by an interrupted attempt of this one).
    skipped
        Manifest paths already present and correct.
    bytes_downloaded
        Bytes received over the network by this call.
    """

    dataset: str
    root: Path
    n_files: int
    downloaded: tuple[str, ...] = ()
    resumed: tuple[str, ...] = ()
    skipped: tuple[str, ...] = ()
    bytes_downloaded: int = 0

    def __str__(self) -> str:
        resumed = f", {len(self.resumed)} resumed" if self.resumed else ""
        return (f"{self.dataset}: {len(self.downloaded)} file(s) downloaded "
                f"({self.bytes_downloaded / 1e6:.1f} MB{resumed}), {len(self.skipped)} already correct, "
                f"in {self.root}")


def file_url(base_url: str, path: str) -> str:
    """Download URL of manifest ``path``: ``base_url`` + the percent-encoded path."""
    return base_url.rstrip("/") + "/" + urllib.parse.quote(path, safe="/")


def _stream(url: str, rel: str, part: Path, size_bytes: int, timeout_s: float,
            on_bytes) -> bool:
    """Append the rest of the file to ``part`` (or rewrite it from the start).

    ``on_bytes(n)`` is called for every chunk received. Returns whether earlier
    ``part`` bytes were kept (the server honoured the ``Range`` request).
    """
    offset = part.stat().st_size if part.exists() else 0
    headers = {"User-Agent": _USER_AGENT, "Accept-Encoding": "identity"}
    if offset:
        headers["Range"] = f"bytes={offset}-"
    try:
        resp = urllib.request.urlopen(urllib.request.Request(url, headers=headers), timeout=timeout_s)
    except urllib.error.HTTPError as exc:
        exc.close()  # an HTTPError holds the open error response
        if exc.code == 416 and offset:
            part.unlink()  # the server cannot continue from our partial data: start over
            raise _Interrupted("server refused to resume (HTTP 416)") from None
        raise FetchError(f"{rel}: HTTP {exc.code} {exc.reason} from {url}", path=rel, url=url) from None
    except (urllib.error.URLError, OSError, http.client.HTTPException) as exc:
        raise _Interrupted(f"could not connect: {getattr(exc, 'reason', exc)}") from None

    with resp:
        if offset and resp.status == 206:
            match = _CONTENT_RANGE_RE.match(resp.headers.get("Content-Range", ""))
            if not match or int(match.group(1)) != offset:
                part.unlink()
                raise _Interrupted(f"server answered the range request from the wrong offset "
                                   f"(Content-Range {resp.headers.get('Content-Range')!r})")
            mode, kept = "ab", True
        elif resp.status == 200:
            mode, kept, offset = "wb", False, 0  # full body: Range ignored or not sent
        else:
            raise FetchError(f"{rel}: unexpected HTTP {resp.status} from {url}", path=rel, url=url)

        received = 0
        with open(part, mode) as fh:
            while True:
                try:
                    chunk = resp.read(_CHUNK_BYTES)
                except (OSError, http.client.HTTPException) as exc:
                    raise _Interrupted(f"connection lost: {exc}") from None
                if not chunk:
                    break
                if offset + received + len(chunk) > size_bytes:
                    fh.close()
                    part.unlink()
                    raise ChecksumError(
                        f"{rel}: {url} sent more than the {size_bytes} bytes in the manifest; "
                        f"the download was deleted (upstream file changed, or wrong base URL?)",
                        path=rel, url=url)
                fh.write(chunk)
                received += len(chunk)
                on_bytes(len(chunk))
    if offset + received < size_bytes:
        raise _Interrupted(f"connection closed after {offset + received} of {size_bytes} bytes")
    return kept


def _download(url: str, rel: str, final: Path, size_bytes: int, sha256: str, *, timeout_s: float,
              retries: int, on_bytes) -> tuple[int, bool]:
    """Download one file to ``final`` through ``final.part``; returns (bytes received, resumed)."""
    part = final.with_name(final.name + PART_SUFFIX)
    final.parent.mkdir(parents=True, exist_ok=True)
    received, resumed, failures = 0, False, 0

    def count(n: int) -> None:  # counts bytes of interrupted attempts too
        nonlocal received
        received += n
        on_bytes(n)

    while True:
        if part.exists() and part.stat().st_size > size_bytes:
            part.unlink()
        uses_old_bytes = part.exists() and part.stat().st_size > 0
        try:
            if not part.exists() or part.stat().st_size < size_bytes:
                kept = _stream(url, rel, part, size_bytes, timeout_s, count)
                uses_old_bytes = uses_old_bytes and kept
        except _Interrupted as exc:
            failures += 1
            if failures > retries:
                have = part.stat().st_size if part.exists() else 0
                kept_note = (f"; {have} of {size_bytes} bytes are kept in {part.name} and the next fetch "
                             f"resumes from there" if have else "")
                raise FetchError(f"{rel}: download from {url} failed after {failures} attempt(s) "
                                 f"({exc}){kept_note}", path=rel, url=url) from None
            continue
        resumed = resumed or uses_old_bytes
        digest = sha256_file(part)
        if digest == sha256:
            os.replace(part, final)
            return received, resumed
        part.unlink()
        if uses_old_bytes and failures < retries:
            failures += 1  # the kept partial data may have been the bad part: start clean once
            resumed = False
            continue
        raise ChecksumError(
            f"{rel}: SHA-256 of the data from {url} is {digest}, the manifest expects {sha256}; "
            f"the download was deleted (upstream file changed, or wrong base URL?)", path=rel, url=url)


def fetch(name: str, dest: str | os.PathLike | None = None, *,
          manifest: pd.DataFrame | str | os.PathLike | None = None, base_url: str | None = None,
          timeout_s: float = 60.0, retries: int = 2, progress: bool = True) -> FetchReport:
    """Download the files of dataset ``name`` that are missing or wrong under ``dest/name``.

    Parameters
    ----------
    name
        Dataset name as in the manifest, e.g. ``"hanyang-outdoor-uwb"``.
    dest
        Data directory; the dataset goes to ``dest/name``. Default
        :data:`~uwbwb.datasets.discovery.EXTERNAL_DIR` (``data/external``), which
        the data discovery searches.
    manifest
        Manifest table or CSV path; default ``data/manifest.csv``.
    base_url
        Overrides the dataset's ``base_url`` from ``data/datasets.json``.
    timeout_s
        Socket timeout per connect/read, in seconds.
    retries
        Extra attempts per file after an interrupted transfer (each resumes
        with a ``Range`` request), or after a checksum failure of resumed data.
    progress
        Show a byte progress bar (``tqdm``).

    Returns
    -------
    FetchReport

    Raises
    ------
    ValueError
        Unknown dataset, or no base URL known for it.
    FetchError
        HTTP error, or a transfer that kept failing; names the file and URL.
        A ``.part`` file is left for the next call to resume.
    ChecksumError
        The received bytes do not match the manifest; they are deleted.

    Files finished before an error stay in place (verified) and are skipped by
    the next call. The exception's ``report`` attribute says what was done.
    """
    files = dataset_files(name, manifest)
    if base_url is None:
        infos = load_datasets_info()
        if name not in infos:
            raise ValueError(f"no base URL known for dataset {name!r}; pass base_url")
        base_url = infos[name].base_url
    if not urllib.parse.urlsplit(base_url).scheme:
        raise ValueError(f"base URL {base_url!r} is not a URL (expected e.g. https://...)")
    root = Path(EXTERNAL_DIR if dest is None else dest).expanduser() / name

    skipped, todo = [], []
    for row in files.itertuples(index=False):
        status, _ = file_status(root / row.path, row.size_bytes, row.sha256)
        (skipped if status == "ok" else todo).append(row)

    from tqdm.auto import tqdm

    downloaded, resumed, n_bytes = [], [], 0

    def report() -> FetchReport:
        return FetchReport(dataset=name, root=root, n_files=len(files), downloaded=tuple(downloaded),
                           resumed=tuple(resumed), skipped=tuple(r.path for r in skipped),
                           bytes_downloaded=n_bytes)

    with tqdm(total=sum(r.size_bytes for r in todo), unit="B", unit_scale=True, desc=name,
              disable=not progress or not todo) as bar:
        for row in todo:
            url = file_url(base_url, row.path)
            try:
                got, was_resumed = _download(url, row.path, root / row.path, row.size_bytes, row.sha256,
                                             timeout_s=timeout_s, retries=retries, on_bytes=bar.update)
            except FetchError as exc:
                exc.report = report()
                raise
            n_bytes += got
            downloaded.append(row.path)
            if was_resumed:
                resumed.append(row.path)
    return report()
