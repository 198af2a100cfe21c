"""One table of every known dataset: where it was found, file status, recordings."""

from __future__ import annotations

import importlib
import os

import pandas as pd

from ..errors import DataNotFoundError
from .discovery import data_dirs, find_dataset
from .manifest import load_datasets_info, load_manifest, verify


def overview(data_dir: str | os.PathLike | None = None, *, check: bool = True) -> pd.DataFrame:
    """Every dataset in the manifest with where it was found and what it holds.

    Parameters
    ----------
    data_dir
        Search only this folder (a notebook's ``DATA_DIR``); None = the usual order.
    check
        Verify sizes and sha256 checksums against the manifest (~70 MB read).

    Returns
    -------
    DataFrame
        ``dataset, found_at, origin, files_ok, files_missing, files_mismatch,
        recordings, licence``; a dataset that is absent has empty location and a
        note on how to fetch it in ``origin``.
    """
    manifest = load_manifest()
    infos = load_datasets_info()
    candidates = data_dirs(data_dir)
    if data_dir is not None:
        candidates = candidates[:1]
    rows = []
    for name in dict.fromkeys(manifest["dataset"]):
        info = infos.get(name)
        row = {"dataset": name, "found_at": "", "origin": f"absent: python -m uwbwb fetch {name}",
               "files_ok": 0, "files_missing": 0, "files_mismatch": 0, "recordings": 0,
               "licence": info.license if info else ""}
        try:
            root = find_dataset(name, data_dir)
        except DataNotFoundError:
            rows.append(row)
            continue
        row["found_at"] = str(root)
        row["origin"] = next((o for o, base in candidates if base / name == root), "")
        if check:
            status = verify(name, root, manifest=manifest)["status"]
            row["files_ok"] = int((status == "ok").sum())
            row["files_missing"] = int((status == "missing").sum())
            row["files_mismatch"] = int(status.isin(["size_mismatch", "sha_mismatch"]).sum())
        if info is not None and info.loader:
            row["recordings"] = len(importlib.import_module(info.loader).list_recordings(data_dir=root.parent))
        rows.append(row)
    return pd.DataFrame(rows)
