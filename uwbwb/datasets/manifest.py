"""Manifest of the public datasets: one row per file with its size and SHA-256.

``data/manifest.csv`` has the columns ``dataset, path, size_bytes, sha256``;
``path`` is relative to the dataset root and uses forward slashes. The dataset
root mirrors the root of the upstream repository, so the download URL of a file
is the dataset's ``base_url`` (in ``data/datasets.json``) followed by ``path``.

``data/datasets.json`` holds, per dataset, the upstream repository, its licence,
whether the files may be redistributed, the base URL for raw files, a citation
line and the loader module. Correct ``base_url`` there if upstream moves or
renames its default branch.

Provenance: the checksums are those of the published copies the project was
built and tested against (the shared dataset folder). The URLs are the upstream
raw-file locations of the repositories' default branches; they could not be
reached from the machine that built the manifest and are unverified. If upstream
changes a file, :func:`verify` and ``fetch`` report it as a mismatch rather than
accepting different data.

Maintainer command (regenerates the manifest from a folder that holds one
sub-folder per dataset; never edit the CSV by hand)::

    python -m uwbwb.datasets.manifest build SRC_DIR [--out data/manifest.csv] [--dataset NAME ...]

With ``--dataset`` only those datasets are rescanned; the rows of the others
are kept from the existing output file.

A local copy is checked against the manifest by ``python -m uwbwb datasets`` (:func:`verify`).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import re
import sys
from pathlib import Path

import pandas as pd

from ..errors import DataFormatError
from .discovery import PROJECT_ROOT, find_dataset

#: The committed manifest.
MANIFEST_PATH = PROJECT_ROOT / "data" / "manifest.csv"
#: Per-dataset metadata: repository, licence, base URL, citation, loader.
DATASETS_PATH = PROJECT_ROOT / "data" / "datasets.json"
#: Manifest columns, in order.
COLUMNS = ("dataset", "path", "size_bytes", "sha256")
#: Per-file outcomes of :func:`verify`.
STATUSES = ("ok", "missing", "size_mismatch", "sha_mismatch")
#: Suffix of a partly downloaded file (see :mod:`uwbwb.datasets.fetch`).
PART_SUFFIX = ".part"

_SHA256_RE = re.compile(r"[0-9a-f]{64}")
_CHUNK_BYTES = 1 << 20


@dataclasses.dataclass(frozen=True)
class DatasetInfo:
    """Where a dataset comes from and how it may be used.

    Attributes
    ----------
    name
        Dataset name as in the manifest, e.g. ``"lias-planar-uwb"``.
    repository
        Upstream repository URL.
    license
        SPDX identifier, or a plain statement when upstream has no licence.
    redistributable
        False when the files must not be copied anywhere but the user's machine.
    base_url
        Raw-file URL of the repository's default branch; file URL = ``base_url + path``.
    citation
        One line to cite when using the data.
    loader
        Dotted name of the loader module (exposes ``NAME`` and ``list_recordings``).
    note
        Usage note shown by ``python -m uwbwb datasets`` and ``fetch``.
    """

    name: str
    repository: str
    license: str
    redistributable: bool
    base_url: str
    citation: str
    loader: str = ""
    note: str = ""


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file, read in chunks (memory use independent of file size)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK_BYTES):
            digest.update(chunk)
    return digest.hexdigest()


def _check_relative_path(path: str) -> str | None:
    """Why ``path`` is not a safe manifest path, or None when it is."""
    if not path:
        return "empty path"
    if "\\" in path:
        return f"path {path!r} must use forward slashes"
    if path.startswith("/") or re.match(r"[A-Za-z]:", path):
        return f"path {path!r} must be relative to the dataset root"
    if any(part in ("", ".", "..") for part in path.split("/")):
        return f"path {path!r} has an empty, '.' or '..' component"
    if path.endswith(PART_SUFFIX):
        return f"path {path!r} is a partial download ({PART_SUFFIX})"
    return None


def load_manifest(path: str | os.PathLike | None = None) -> pd.DataFrame:
    """Read and validate a manifest.

    Parameters
    ----------
    path
        Manifest CSV; default :data:`MANIFEST_PATH` (``data/manifest.csv``).

    Returns
    -------
    pandas.DataFrame
        Columns ``dataset`` (str), ``path`` (str, relative, forward slashes),
        ``size_bytes`` (int64), ``sha256`` (64 lowercase hex digits), in file order.

    Raises
    ------
    DataFormatError
        Wrong header, a bad size or checksum, an unsafe path or a duplicate row,
        naming the line.
    """
    path = Path(MANIFEST_PATH if path is None else path)
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise DataFormatError(path, f"not a readable CSV manifest ({exc})") from None
    if tuple(df.columns) != COLUMNS:
        raise DataFormatError(path, f"header must be {','.join(COLUMNS)}, found {','.join(map(str, df.columns))}",
                              line=1)
    for i, row in enumerate(df.itertuples(index=False)):
        line = i + 2  # 1-based, after the header
        if not row.dataset:
            raise DataFormatError(path, "empty dataset name", line=line, column="dataset")
        problem = _check_relative_path(row.path)
        if problem:
            raise DataFormatError(path, problem, line=line, column="path")
        if not row.size_bytes.isdigit():
            raise DataFormatError(path, f"size_bytes must be a non-negative integer, found {row.size_bytes!r}",
                                  line=line, column="size_bytes")
        if not _SHA256_RE.fullmatch(row.sha256):
            raise DataFormatError(path, f"sha256 must be 64 lowercase hex digits, found {row.sha256!r}",
                                  line=line, column="sha256")
    dup = df.duplicated(["dataset", "path"], keep="first")
    if dup.any():
        i = int(dup.to_numpy().nonzero()[0][0])
        raise DataFormatError(path, f"duplicate row for {df.dataset.iat[i]}/{df.path.iat[i]}", line=i + 2)
    return df.astype({"size_bytes": "int64"})


def load_datasets_info(path: str | os.PathLike | None = None) -> dict[str, DatasetInfo]:
    """Read ``data/datasets.json`` (or ``path``) into ``{name: DatasetInfo}``."""
    path = Path(DATASETS_PATH if path is None else path)
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise DataFormatError(path, f"invalid JSON: {exc.msg}", line=exc.lineno, column=exc.colno) from None
    entries = raw.get("datasets") if isinstance(raw, dict) else None
    if not isinstance(entries, dict):
        raise DataFormatError(path, 'expected an object with a "datasets" object inside')
    fields = {f.name for f in dataclasses.fields(DatasetInfo)} - {"name"}
    required = {f.name for f in dataclasses.fields(DatasetInfo)
                if f.default is dataclasses.MISSING} - {"name"}
    infos = {}
    for name, entry in entries.items():
        if not isinstance(entry, dict):
            raise DataFormatError(path, f"dataset {name!r}: expected an object")
        missing = required - set(entry)
        unknown = set(entry) - fields
        if missing or unknown:
            raise DataFormatError(path, f"dataset {name!r}: missing keys {sorted(missing)}, "
                                        f"unknown keys {sorted(unknown)}")
        infos[name] = DatasetInfo(name=name, **entry)
    return infos


def dataset_files(name: str, manifest: pd.DataFrame | str | os.PathLike | None = None) -> pd.DataFrame:
    """The manifest rows of dataset ``name`` (index reset).

    Raises
    ------
    ValueError
        When the manifest has no dataset of that name (the message lists those it has).
    """
    df = manifest if isinstance(manifest, pd.DataFrame) else load_manifest(manifest)
    rows = df[df["dataset"] == name].reset_index(drop=True)
    if rows.empty:
        known = ", ".join(dict.fromkeys(df["dataset"])) or "none"
        raise ValueError(f"unknown dataset {name!r}; the manifest lists: {known}")
    return rows


def file_status(path: Path, size_bytes: int, sha256: str) -> tuple[str, int | None]:
    """Status of one file against its manifest entry, and its actual size (None when missing).

    The size is compared first, so a wrong-sized file is not hashed.
    """
    try:
        actual = path.stat().st_size
    except FileNotFoundError:
        return "missing", None
    if not path.is_file():
        return "missing", None
    if actual != size_bytes:
        return "size_mismatch", actual
    return ("ok" if sha256_file(path) == sha256 else "sha_mismatch"), actual


def verify(name: str, root: str | os.PathLike | None = None, *,
           manifest: pd.DataFrame | str | os.PathLike | None = None) -> pd.DataFrame:
    """Check every manifest file of dataset ``name`` under ``root``.

    Parameters
    ----------
    name
        Dataset name, e.g. ``"iasl-uwb-imu"``.
    root
        Dataset root folder; default :func:`~uwbwb.datasets.discovery.find_dataset` ``(name)``.
    manifest
        Manifest table or CSV path; default the committed manifest.

    Returns
    -------
    pandas.DataFrame
        One row per manifest file: ``path``, ``status`` (one of :data:`STATUSES`),
        ``size_bytes`` (expected), ``actual_size_bytes`` (``<NA>`` when missing).
        Files present under ``root`` but not in the manifest are not listed.
    """
    files = dataset_files(name, manifest)
    root = find_dataset(name) if root is None else Path(root)
    statuses, sizes = [], []
    for row in files.itertuples(index=False):
        status, actual = file_status(root / row.path, row.size_bytes, row.sha256)
        statuses.append(status)
        sizes.append(actual)
    return pd.DataFrame({
        "path": files["path"],
        "status": pd.Categorical(statuses, categories=STATUSES),
        "size_bytes": files["size_bytes"],
        "actual_size_bytes": pd.array(sizes, dtype="Int64"),
    })


def scan(root: str | os.PathLike, name: str) -> pd.DataFrame:
    """Manifest rows for every regular file under ``root`` (sorted by path).

    Raises
    ------
    ValueError
        If a partial download (``*.part``) or a non-portable path is found: the
        manifest must describe complete, published files only.
    """
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"{root} is not a directory")
    files = {p.relative_to(root).as_posix(): p for p in root.rglob("*") if p.is_file()}
    rows = []
    for rel, file in sorted(files.items()):
        problem = _check_relative_path(rel)
        if problem:
            raise ValueError(f"{file}: {problem}; remove it before building the manifest")
        rows.append((name, rel, file.stat().st_size, sha256_file(file)))
    return pd.DataFrame(rows, columns=list(COLUMNS)).astype({"size_bytes": "int64"})


def build(src_dir: str | os.PathLike, out: str | os.PathLike | None = None,
          datasets: list[str] | None = None) -> pd.DataFrame:
    """Regenerate the manifest from ``src_dir/<dataset>/`` folders and write it.

    Parameters
    ----------
    src_dir
        Folder holding one sub-folder per dataset (e.g. ``../shared/datasets``).
    out
        Output CSV; default :data:`MANIFEST_PATH`.
    datasets
        Datasets to rescan; default every dataset in ``data/datasets.json``.
        When given, the rows of the other datasets already in ``out`` are kept.

    Returns
    -------
    pandas.DataFrame
        The manifest written.
    """
    src_dir, out = Path(src_dir), Path(MANIFEST_PATH if out is None else out)
    names = list(datasets) if datasets else list(load_datasets_info())
    missing = [n for n in names if not (src_dir / n).is_dir()]
    if missing:
        raise ValueError(f"{src_dir} lacks dataset folder(s): {', '.join(missing)}")
    frames = [scan(src_dir / n, n) for n in names]
    if datasets and out.exists():
        kept = load_manifest(out)
        frames.insert(0, kept[~kept["dataset"].isin(names)])
    df = pd.concat(frames, ignore_index=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    df.to_csv(tmp, index=False, lineterminator="\n")
    os.replace(tmp, out)
    return df


def _main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m uwbwb.datasets.manifest",
                                     description="Build the dataset manifest (python -m uwbwb datasets "
                                                 "checks a copy against it).")
    sub = parser.add_subparsers(dest="command", required=True)
    p_build = sub.add_parser("build", help="regenerate the manifest from SRC_DIR/<dataset>/ folders")
    p_build.add_argument("src_dir", metavar="SRC_DIR")
    p_build.add_argument("--out", default=None, help=f"output CSV (default {MANIFEST_PATH})")
    p_build.add_argument("--dataset", action="append", default=None, metavar="NAME",
                         help="rescan only this dataset (repeatable); other rows are kept")
    args = parser.parse_args(argv)
    try:
        df = build(args.src_dir, args.out, args.dataset)
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    counts = df.groupby("dataset", sort=False).agg(files=("path", "size"), bytes=("size_bytes", "sum"))
    print(counts.to_string())
    print(f"wrote {Path(args.out or MANIFEST_PATH)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(_main())
