"""Command line: ``python -m uwbwb`` (or ``uwbwb``).

Commands
--------
``datasets [--data-dir DIR] [--no-verify] [--all]``
    For every dataset in the manifest: where it was found, checksum status
    counts, and the recordings its loader lists.
``fetch NAME [--dest DIR] [--base-url URL]``
    Download a dataset from upstream with checksum verification (resumable).
``reproduce [--quick] [--only NB ...] [--out DIR] [--notebooks-dir DIR] [-p KEY VALUE ...] [--timeout S] [--jobs N] [--force] [--scheduler ADDRESS] [--scheduler-timeout S]``
    Execute the notebooks headless; write executed notebooks, HTML and
    ``summary.json`` / ``summary.md`` (default into ``reports/``).

``score TARGET [--out DIR] [--calibrate-on SPEC] [--fraction F] [--tags ...] [--methods ...] [--rate-hz R] [--tag-height-m Z] [--truth-offset-s S] [--fast]``
    Every estimator on one recording (``DATASET/RECORDING`` or a tidy CSV folder) against one
    common bound and its own Cramér–Rao bound: calibration and tuning on the first ``F`` of the
    run (or on another recording), scoring on the rest; a recording whose ranges do not fit its
    anchors and truth is refused with a diagnosis (units, axes, clock offset, anchors); writes
    ``scoreboard.csv``, ``scoreboard.md`` and ``scoreboard.png`` into ``--out`` (default
    ``reports/score/<recording>``). Estimates made outside the workbench that the recording brings
    (a tidy folder's ``external/*.csv``, a Hanyang case's ``LS.csv`` / ``ESKF.csv``) join the board
    as *external* rows, whatever ``--methods`` says; a method that does not apply (the TDoA methods
    where the TDoAs are uninformative, the UWB/INS filters without an IMU) says why in its note.

The notebook and report folders are arguments of :func:`main` (defaults ``notebooks/`` and
``reports/`` in the working directory), the data folder the commands' ``--data-dir``; nothing is
found relative to the installed package, so the command line also works from a wheel.

Exit codes: 0 success; 1 failure (``datasets``: a dataset absent or a file
missing or wrong; ``fetch``: a download failed; ``reproduce``: a notebook failed
or wrote no summary); 2 bad arguments.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path
from typing import Sequence

from .. import reproduce as rp
from ..datasets.discovery import data_dirs, find_dataset
from ..datasets.fetch import FetchError, fetch
from ..datasets.manifest import dataset_files, load_datasets_info, load_manifest, verify
from ..errors import DataNotFoundError

#: Recordings listed per dataset before "... and N more" (``--all`` lists every one).
MAX_RECORDINGS_SHOWN = 12


def _build_parser() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The top-level parser and the parser of each command (for command-specific usage errors)."""
    parser = argparse.ArgumentParser(
        prog="python -m uwbwb",
        description="uwbwb — a Jupyter workbench for indoor UWB positioning research.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("datasets", help="where each dataset is, checksum status, recordings",
                       description="For every dataset in the manifest: where it was found, how its "
                                   "files compare with the manifest checksums, and its recordings.")
    p.add_argument("--data-dir", metavar="DIR", default=None,
                   help="look only in DIR (a folder holding one sub-folder per dataset)")
    p.add_argument("--no-verify", action="store_true",
                   help="only check that files exist (skip sizes and SHA-256)")
    p.add_argument("--all", action="store_true", help="list every recording")

    p = sub.add_parser("fetch", help="download a dataset from upstream, verified against the manifest",
                       description="Download the files of dataset NAME that are missing or wrong, "
                                   "verify each against the manifest SHA-256, resume interrupted "
                                   "downloads, skip files already correct.")
    p.add_argument("name", metavar="NAME", help="dataset name (see `python -m uwbwb datasets`)")
    p.add_argument("--dest", metavar="DIR", default=None,
                   help="data directory to write NAME/ into (default data/external)")
    p.add_argument("--base-url", metavar="URL", default=None,
                   help="raw-file URL of the upstream repository (default from data/datasets.json)")
    p.add_argument("--timeout", metavar="S", type=_positive_float, default=60.0,
                   help="network timeout per connect/read in seconds (default 60)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")

    p = sub.add_parser("reproduce", help="execute the notebooks and collect their headline numbers",
                       description="Execute notebooks/*.ipynb with papermill; write <stem>.ipynb, "
                                   "<stem>.html, <stem>.summary.json and the aggregated "
                                   "summary.json / summary.md into the output folder.")
    p.add_argument("--quick", action="store_true",
                   help="pass FAST=True (small, CI-sized experiments); refused with -p FAST False or with a -p value "
                        "that a notebook's FAST mode would replace or lower")
    p.add_argument("--only", nargs="+", action="extend", metavar="NB", default=None,
                   help="run only notebooks whose stem starts with NB (e.g. 00 or 00_quickstart)")
    p.add_argument("--out", metavar="DIR", default=None, help="output folder (default reports/)")
    p.add_argument("--notebooks-dir", metavar="DIR", default=None,
                   help="folder holding the notebooks (default notebooks/ in the working directory)")
    p.add_argument("-p", "--parameter", nargs=2, action="append", metavar=("KEY", "VALUE"), default=[],
                   help="notebook parameter, given to every selected notebook that declares it; "
                        "VALUE is checked against the notebook's specification of NAME (type, range, what None "
                        "means; uwbwb/notebook_params.py) and reaches the notebook with that type (text stays "
                        "text: -p STATIC_SESSION 8.20; True/False; numbers and tuples as Python literals: "
                        "-p SIGMA_D_CMPS '(2.5, 4, 40)'). Unknown names and values that do not fit are errors")
    p.add_argument("--timeout", metavar="S", type=_positive_float, default=None,
                   help="execution timeout per cell in seconds (default none)")
    p.add_argument("--jobs", metavar="N", type=int, default=None,
                   help="notebooks executed at once, each in its own process (default: one per core; 1: one after "
                        "the other). The numbers do not depend on it")
    p.add_argument("--force", action="store_true",
                   help="execute every notebook; without it a notebook whose source, parameters, package source, "
                        "environment and data files are those of its last successful run into --out is reused")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run the notebooks concurrently on a Dask cluster: 'local' (a LocalCluster sized to this "
                        "machine) or a scheduler address such as tcp://10.0.0.5:8786; each notebook gets it as "
                        "DASK_SCHEDULER, so its sweeps run there too (needs uwbwb[dask])")
    p.add_argument("--scheduler-timeout", metavar="S", type=_positive_float, default=None,
                   help="seconds a scheduler address (--scheduler or -p DASK_SCHEDULER) has to answer as a Dask "
                        "scheduler before the command stops with an error (default 5, or $UWBWB_SCHEDULER_TIMEOUT_S); "
                        "the notebooks' own connections use it too")

    p = sub.add_parser("score", help="every estimator on one recording, against the Cramér–Rao bound",
                       description="Calibrate on one part of a recording (or another recording), score every "
                                   "estimator on the rest, and write the board (CSV, Markdown, figure).")
    p.add_argument("target", metavar="TARGET",
                   help="DATASET/RECORDING (e.g. lias-planar-uwb/fast, iasl-uwb-imu/scenario2) or a folder "
                        "holding ranges.csv, anchors.csv and truth.csv in the tidy format (outside estimates in "
                        "external/*.csv beside them join as external rows)")
    p.add_argument("--out", metavar="DIR", default=None, help="output folder (default reports/score/<name>)")
    p.add_argument("--calibrate-on", metavar="SPEC", default=None,
                   help="calibrate on this recording (same anchors and tags) instead of the first part")
    p.add_argument("--fraction", metavar="F", type=float, default=0.5,
                   help="share of the run (from its start) used for calibration when no --calibrate-on (0.5)")
    p.add_argument("--tags", nargs="+", metavar="TAG", default=None, help="tags to score (default all with truth)")
    p.add_argument("--rate-hz", metavar="R", type=_positive_float, default=10.0,
                   help="rate every method runs at; ranges are thinned to it (default 10)")
    p.add_argument("--data-dir", metavar="DIR", default=None, help="folder holding the datasets")
    p.add_argument("--methods", nargs="+", metavar="NAME", default=None,
                   help="only these methods (names as in the table, e.g. LS EKF-RF 'EKF-RF ranges' 'set-noise KF'); "
                        "the recording's external rows are always shown")
    p.add_argument("--tag-height-m", metavar="Z", type=float, default=None,
                   help="tag height for a 2-D truth.csv (default: fitted from the calibration part's ranges)")
    p.add_argument("--truth-offset-s", metavar="S", type=float, default=0.0,
                   help="truth clock offset to remove (truth time = range time + S), e.g. the estimate a refused "
                        "recording reports")
    p.add_argument("--fast", action="store_true", help="CI-sized tuning grids and particle counts")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    return parser, sub.choices


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


# -- datasets ---------------------------------------------------------------------------------------

def _indent(text: str, prefix: str = "    ") -> str:
    return "\n".join(prefix + line for line in text.splitlines())


def _locate(name: str, data_dir: str | None) -> tuple[Path | None, str]:
    """Dataset root (or None) and a line saying where it was found or where it was looked for."""
    candidates = data_dirs(data_dir)
    if data_dir is not None:
        candidates = candidates[:1]
    try:
        root = find_dataset(name, data_dir)
    except DataNotFoundError:
        searched = ", ".join(str(base) for _, base in candidates)
        return None, f"not found (searched {searched}); get it with: python -m uwbwb fetch {name}"
    origin = next((o for o, base in candidates if (base / name) == root), "")
    return root, f"{root}" + (f"  [{origin}]" if origin else "")


def _checksum_lines(name: str, root: Path, manifest, verify_checksums: bool) -> tuple[list[str], int]:
    """Lines on the files' state, and the number of files not ok."""
    if verify_checksums:
        report = verify(name, root, manifest=manifest)
        counts = report["status"].value_counts()
        n_mismatch = int(counts["size_mismatch"] + counts["sha_mismatch"])
        lines = [f"checksums:  {counts['ok']} ok, {counts['missing']} missing, {n_mismatch} mismatch "
                 f"(of {len(report)} files in the manifest)"]
        bad = report[report["status"] != "ok"]
    else:
        files = dataset_files(name, manifest)
        present = [(root / p).is_file() for p in files["path"]]
        lines = [f"files:      {sum(present)} of {len(files)} present (checksums not verified)"]
        bad = files.loc[[not p for p in present]].assign(status="missing")
    for row in bad.head(5).itertuples(index=False):
        lines.append(f"            {row.status}: {row.path}")
    if len(bad) > 5:
        lines.append(f"            ... and {len(bad) - 5} more")
    return lines, len(bad)


def _cell_text(value, root: Path | None) -> str:
    if value is None or (isinstance(value, float) and value != value):
        return ""  # missing: blank rather than "nan"
    if isinstance(value, float):
        return f"{value:.6g}"
    text = str(value)
    if root is not None and isinstance(value, (str, Path)):
        prefix = str(root) + "/"
        if text.startswith(prefix):
            return text[len(prefix):]
    return text


def _table_text(table, root: Path | None = None) -> str:
    """A DataFrame as plain text: text columns aligned left, numbers right, blanks for
    missing values, and paths under ``root`` shown relative to it."""
    columns = []
    for col in table.columns:
        numeric = table[col].dtype.kind in "biuf"
        cells = [_cell_text(v, root) for v in table[col]]
        width = max([len(str(col)), *map(len, cells)])
        align = str.rjust if numeric else str.ljust
        columns.append([align(str(col), width), *(align(c, width) for c in cells)])
    return "\n".join("  ".join(row).rstrip() for row in zip(*columns))


def _recording_lines(info, root: Path, show_all: bool) -> list[str]:
    """The loader's recording table (paths relative to ``root``), or why it is unavailable.

    Never raises: a missing or broken loader must not stop the overview of the others.
    """
    module_name = info.loader if info is not None else ""
    if not module_name:
        return ["recordings: recording listing unavailable (no loader registered in data/datasets.json)"]
    try:
        module = importlib.import_module(module_name)
        list_recordings = module.list_recordings
    except Exception as exc:  # absent (not written yet, not installed) or broken on import
        return [f"recordings: recording listing unavailable ({module_name}: {type(exc).__name__}: {exc})"]
    try:
        table = list_recordings(data_dir=root.parent)
    except Exception as exc:  # the loader's own error is reported, the next dataset still shown
        return [f"recordings: recording listing failed ({module_name}: {type(exc).__name__}: {exc})"]
    n = len(table)
    shown = table if show_all or n <= MAX_RECORDINGS_SHOWN else table.head(MAX_RECORDINGS_SHOWN)
    lines = [f"recordings: {n}" + (" (paths relative to the dataset root)" if n else "")]
    if n:
        lines.append(_indent(_table_text(shown, root)))
    if len(shown) < n:
        lines.append(f"    ... and {n - len(shown)} more (--all lists every one)")
    return lines


def cmd_datasets(args: argparse.Namespace) -> int:
    manifest = load_manifest()
    infos = load_datasets_info()
    names = list(dict.fromkeys(manifest["dataset"]))
    all_ok = True
    for k, name in enumerate(names):
        info = infos.get(name)
        if k:
            print()
        print(name)
        if info is not None:
            print(f"  upstream:   {info.repository}  (licence: {info.license})")
            if not info.redistributable:
                print(f"  note:       {info.note}")
        root, where = _locate(name, args.data_dir)
        print(f"  found:      {where}")
        if root is None:
            all_ok = False
            continue
        lines, n_bad = _checksum_lines(name, root, manifest, not args.no_verify)
        all_ok = all_ok and n_bad == 0
        lines += _recording_lines(info, root, args.all)
        print(_indent("\n".join(lines), "  "))
    return 0 if all_ok else 1


# -- fetch ------------------------------------------------------------------------------------------

def cmd_fetch(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    manifest = load_manifest()
    known = list(dict.fromkeys(manifest["dataset"]))
    if args.name not in known:
        parser.error(f"unknown dataset {args.name!r}; choose from: {', '.join(known)}")
    info = load_datasets_info().get(args.name)
    if info is not None:
        print(f"{args.name}: {info.repository} (licence: {info.license})")
        if not info.redistributable:
            print(f"note: {info.note}")
    try:
        report = fetch(args.name, args.dest, manifest=manifest, base_url=args.base_url,
                       timeout_s=args.timeout, progress=not args.quiet)
    except FetchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        if exc.report is not None and exc.report.downloaded:
            print(f"({len(exc.report.downloaded)} file(s) were completed before the error and are kept; "
                  f"run the command again to continue)", file=sys.stderr)
        return 1
    print(report)
    if info is not None:
        print(f"cite: {info.citation}")
    return 0


# -- reproduce --------------------------------------------------------------------------------------

def cmd_reproduce(args: argparse.Namespace, parser: argparse.ArgumentParser, *,
                  notebooks_dir: str | Path | None = None, reports_dir: str | Path | None = None) -> int:
    if args.notebooks_dir is not None:
        notebooks_dir = Path(args.notebooks_dir)
        if not notebooks_dir.is_dir():
            parser.error(f"--notebooks-dir {args.notebooks_dir}: no such folder")
    text = {}
    for key, value in args.parameter:
        if not key.isidentifier():
            parser.error(f"-p {key}: parameter names must be Python identifiers")
        if key in text:
            parser.error(f"-p {key} given twice")
        text[key] = value
    if args.scheduler is not None:
        try:
            import distributed  # noqa: F401
        except ImportError:
            parser.error("--scheduler needs dask.distributed: pip install 'uwbwb[dask]'")
    try:  # every problem with the selection, the settings or the parameters is reported before any notebook runs
        result = rp.reproduce(quick=args.quick, only=args.only, out=args.out or reports_dir, text_parameters=text,
                              notebooks_dir=notebooks_dir, timeout_s=args.timeout, scheduler=args.scheduler,
                              scheduler_timeout_s=args.scheduler_timeout, log=lambda line: print(line, flush=True),
                              force=args.force, jobs=args.jobs)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"wrote {result.summary_md} and {result.summary_json}")
    for run in result.failed:
        print(f"FAILED {run.notebook}: {run.error}", file=sys.stderr)
    return result.exit_code


def main(argv: Sequence[str] | None = None, *, notebooks_dir: str | Path | None = None,
         reports_dir: str | Path | None = None) -> int:
    """Run the command line; returns the exit code (2 for bad arguments).

    ``notebooks_dir`` (default :data:`uwbwb.reproduce.NOTEBOOKS_DIR`, ``notebooks/`` in the working
    directory) is where ``reproduce`` finds the notebooks; ``reports_dir`` (default ``reports/`` in the
    working directory) is where ``reproduce`` and ``score`` write when no ``--out`` is given. Nothing
    is looked up relative to the installed package. The data folder is each command's ``--data-dir``
    (``reproduce``: ``-p DATA_DIR DIR``), default the search order of :mod:`uwbwb.datasets.discovery`.
    """
    parser, commands = _build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help(sys.stderr)
            return 2
        if args.command == "datasets":
            return cmd_datasets(args)
        if args.command == "fetch":
            return cmd_fetch(args, commands["fetch"])
        if args.command == "score":
            from .score import cmd_score      # the scoreboard's imports cost seconds: only for this command

            return cmd_score(args, commands["score"], reports_dir=reports_dir)
        return cmd_reproduce(args, commands["reproduce"], notebooks_dir=notebooks_dir, reports_dir=reports_dir)
    except SystemExit as exc:  # argparse reports bad arguments by exiting with status 2
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
