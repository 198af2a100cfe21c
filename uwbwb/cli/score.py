"""``python -m uwbwb score``: every estimator on one recording (see :mod:`uwbwb.cli`)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..scoreboard import default_estimators, score, split_in_time
from ..scoreboard.sources import external_estimators, load_target

__all__ = ["cmd_score"]


def cmd_score(args: argparse.Namespace, parser: argparse.ArgumentParser, *,
              reports_dir: str | Path | None = None) -> int:
    if not 0 < args.fraction < 1:
        parser.error(f"--fraction must be in (0, 1), got {args.fraction}")
    if args.tags is not None and len(set(args.tags)) < len(args.tags):
        parser.error(f"--tags: each tag once, got {args.tags}")
    if args.tag_height_m is not None and not math.isfinite(args.tag_height_m):
        parser.error(f"--tag-height-m must be a finite height in metres, got {args.tag_height_m}")
    estimators = default_estimators(fast=args.fast)
    if args.methods is not None:
        known = [e.name for e in estimators]
        unknown = [m for m in args.methods if m not in known]
        if unknown:
            parser.error(f"--methods: unknown {unknown}; choose from {known}")
        if "set-noise PF" in args.methods and "set-noise KF" not in args.methods:
            args.methods.append("set-noise KF")        # the PF takes the KF's tuning
        estimators = [e for e in estimators if e.name in args.methods]
    rec = load_target(args.target, args.data_dir)
    # outside estimates the recording brings join as external rows, whatever --methods says (nothing runs)
    estimators += external_estimators(rec)
    if args.calibrate_on is not None:
        cal, test = load_target(args.calibrate_on, args.data_dir), rec
    else:
        cal, test = split_in_time(rec, args.fraction)
    board = score(test, cal, estimators=estimators, tags=args.tags, rate_hz=args.rate_hz, fast=args.fast,
                  progress=not args.quiet, label=rec.label, tag_height_m=args.tag_height_m,
                  truth_offset_s=args.truth_offset_s)
    out = Path(args.out) if args.out else Path(reports_dir or "reports") / "score" / rec.name.replace("/", "_")
    paths = board.write(out)
    print(board.markdown())
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0
