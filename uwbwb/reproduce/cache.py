"""Reuse an executed notebook when nothing it depends on changed.

A notebook run into an output folder leaves ``<stem>.cache.json`` beside its outputs when it succeeded. The next
run into that folder reuses the executed notebook, its HTML and its summary, instead of executing it again, when
the **key** is the same and every **data file** the run read still has the same checksum:

* key — SHA-256 of the notebook's source, its parameters as the runner gives them (``SUMMARY_PATH`` aside: it
  only names the output folder), the package's source (every file under ``uwbwb/``) and the repository's
  ``data/`` folder (manifests, samples), the environment (Python version, every installed distribution and its
  version) and which dataset folders each data location holds (:func:`uwbwb.datasets.discovery.data_dirs`
  with the notebook's ``DATA_DIR``: a dataset that appears or goes changes the key);
* data files — every file the loaders read during the run (:func:`uwbwb.datasets.text._read_bytes` appends each
  path to the file named by :data:`~uwbwb.datasets.text.READ_LOG_ENV`, which the runner sets for the kernel),
  stored with its SHA-256.

Anything else a notebook reads (a file it opens itself) is not seen: ``--force`` (``reproduce(force=True)``)
executes every notebook again. Runs on a Dask cluster (``--scheduler``) are not cached: the read log would be on
the workers.
"""

from __future__ import annotations

import hashlib
import json
import platform
from importlib import metadata, resources
from pathlib import Path
from typing import Any, Mapping

from ..datasets.discovery import PROJECT_ROOT, data_dirs
from ..datasets.manifest import sha256_file

__all__ = ["CACHE_SUFFIX", "forget", "notebook_key", "package_digest", "read_log_path", "valid_entry", "write_entry"]

CACHE_SUFFIX = ".cache.json"


def _tree_digest(root: Path) -> str:
    """SHA-256 over the relative paths and contents of every file under ``root`` (caches left out)."""
    h = hashlib.sha256()
    if root.is_dir():
        for path in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
            h.update(path.relative_to(root).as_posix().encode())
            h.update(sha256_file(path).encode())
    return h.hexdigest()


def _environment() -> list[str]:
    dists = sorted({f"{d.metadata['Name']}=={d.version}" for d in metadata.distributions() if d.metadata["Name"]})
    return [platform.python_version(), *dists]


def _data_locations(data_dir: Any) -> list[str]:
    out = []
    for origin, base in data_dirs(data_dir):
        found = sorted(p.name for p in base.iterdir() if p.is_dir()) if base.is_dir() else []
        out.append(f"{origin}: {base.resolve() if base.exists() else base} {found}")
    return out


def notebook_key(source: Path, parameters: Mapping[str, Any], *, package_digest: str) -> str:
    """The key of one notebook run (module docstring); ``package_digest`` from :func:`package_digest`."""
    h = hashlib.sha256()
    h.update(Path(source).read_bytes())
    shown = {k: repr(v) for k, v in sorted(parameters.items())}
    h.update(json.dumps(shown, sort_keys=True).encode())
    h.update(package_digest.encode())
    h.update("\n".join(_data_locations(parameters.get("DATA_DIR"))).encode())
    return h.hexdigest()


def package_digest() -> str:
    """Digest of the package's source, the repository's ``data/`` folder and the environment (computed once per
    :func:`~uwbwb.reproduce.reproduce` call)."""
    package = Path(str(resources.files("uwbwb")))
    h = hashlib.sha256()
    for part in (_tree_digest(package), _tree_digest(PROJECT_ROOT / "data"), *_environment()):
        h.update(part.encode())
    return h.hexdigest()


def read_log_path(out_dir: Path, stem: str) -> Path:
    """Where the kernel of notebook ``stem`` logs the data files it reads (one path a line)."""
    return out_dir / f".{stem}.reads"


def write_entry(out_dir: Path, stem: str, key: str, seconds: float) -> None:
    """Record a successful run: its key and the checksum of every data file it read."""
    log = read_log_path(out_dir, stem)
    paths = sorted(set(log.read_text(encoding="utf-8").splitlines())) if log.is_file() else []
    log.unlink(missing_ok=True)
    inputs = {p: sha256_file(Path(p)) for p in paths if Path(p).is_file()}
    entry = {"key": key, "inputs": inputs, "seconds": seconds}
    (out_dir / f"{stem}{CACHE_SUFFIX}").write_text(json.dumps(entry, indent=1) + "\n", encoding="utf-8")


def valid_entry(out_dir: Path, stem: str, key: str) -> dict | None:
    """The cache entry of ``stem`` if it can stand for a run with ``key`` now (same key, every data file it read
    unchanged, the executed notebook, HTML and summary present); None otherwise."""
    path = out_dir / f"{stem}{CACHE_SUFFIX}"
    try:
        entry = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(entry, dict) or entry.get("key") != key:
        return None
    if not all((out_dir / f"{stem}{ext}").is_file() for ext in (".ipynb", ".html", ".summary.json")):
        return None
    for p, digest in dict(entry.get("inputs", {})).items():
        if not Path(p).is_file() or sha256_file(Path(p)) != digest:
            return None
    return entry


def forget(out_dir: Path, stem: str) -> None:
    """Remove ``stem``'s cache entry and read log (before it is executed again)."""
    (out_dir / f"{stem}{CACHE_SUFFIX}").unlink(missing_ok=True)
    read_log_path(out_dir, stem).unlink(missing_ok=True)
