"""Where each notebook's time goes: every code cell under cProfile, the top functions per notebook.

Each selected notebook is executed once (papermill, the ``python3`` kernel) with its parameters as
``reproduce`` gives them, plus two cells the runner adds: one first that starts a ``cProfile.Profile`` in the
kernel, one last that stops it and writes its statistics. The profile covers every cell (the kernel runs
them in one thread). Printed per notebook: wall time, profiled time, and the functions with the largest
*own* time (``tottime``) and the package functions with the largest *cumulative* time, each with its calls and
its share of the profiled time. Profiling slows Python-heavy code more than NumPy-heavy code: read the
shares, not the seconds, and compare runs made the same way.

Run:  python benchmarks/profile_notebooks.py [--full] [--only 01 04] [--top 12] [--out DIR]
(default FAST sizes; ``--full`` profiles full fidelity — as long as ``make reproduce``, and longer).
"""

from __future__ import annotations

import argparse
import pstats
import tempfile
import time
from pathlib import Path

import nbformat

from uwbwb import reproduce as rp
from uwbwb.reproduce.running import _papermill

ROOT = Path(__file__).resolve().parents[1]
START = "import cProfile as _cProfile\n_uwbwb_profile = _cProfile.Profile()\n_uwbwb_profile.enable()"
STOP = "_uwbwb_profile.disable()\n_uwbwb_profile.dump_stats({path!r})"


def profile(notebook: Path, params: dict, out_dir: Path) -> tuple[float, Path]:
    """Execute ``notebook`` with the profiler cells into ``out_dir``; (wall seconds, statistics file)."""
    stats = out_dir / f"{notebook.stem}.prof"
    nb = nbformat.read(notebook, as_version=4)
    first = next(i for i, c in enumerate(nb.cells) if c.cell_type == "code")
    nb.cells.insert(first, nbformat.v4.new_code_cell(START))
    nb.cells.append(nbformat.v4.new_code_cell(STOP.format(path=str(stats))))
    source = out_dir / notebook.name
    nbformat.write(nb, source)
    t0 = time.perf_counter()
    _papermill(source, out_dir / f"{notebook.stem}.executed.ipynb", {**params, "SUMMARY_PATH": str(
        out_dir / f"{notebook.stem}.summary.json")}, notebook.parent, None)
    return time.perf_counter() - t0, stats


def report(stem: str, wall_s: float, stats_path: Path, top: int) -> None:
    st = pstats.Stats(str(stats_path))
    total = st.total_tt
    print(f"\n## {stem}: {wall_s:.1f} s wall, {total:.1f} s profiled")
    rows = sorted(st.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
    print(f"{'own s':>8} {'share':>6} {'calls':>10}  function (largest own time)")
    for (file, line, name), (_, calls, tt, _, _) in rows:
        print(f"{tt:8.2f} {tt / total:6.1%} {calls:10d}  {name}  {_short(file)}:{line}")
    own = [(k, v) for k, v in st.stats.items() if "/uwbwb/" in k[0]]
    rows = sorted(own, key=lambda kv: kv[1][3], reverse=True)[:top]
    print(f"{'cum s':>8} {'share':>6} {'calls':>10}  uwbwb function (largest cumulative time)")
    for (file, line, name), (_, calls, _, ct, _) in rows:
        print(f"{ct:8.2f} {ct / total:6.1%} {calls:10d}  {name}  {_short(file)}:{line}")


def _short(file: str) -> str:
    return file[file.index("uwbwb/"):] if "uwbwb/" in file else Path(file).name


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="full fidelity (default: FAST sizes)")
    ap.add_argument("--only", nargs="+", default=None, metavar="NB", help="notebooks whose stem starts with NB")
    ap.add_argument("--top", type=int, default=10, help="functions shown per table (10)")
    ap.add_argument("--out", default=None, help="keep the executed notebooks and .prof files here")
    args = ap.parse_args()
    notebooks = rp.select_notebooks(ROOT / "notebooks", args.only)
    params = rp.resolve_parameters(notebooks, quick=not args.full)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="uwbwb-profile-"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"# Profile of {len(notebooks)} notebook(s), {'full' if args.full else 'FAST'} sizes (files in {out})")
    for nb in notebooks:
        wall, stats = profile(nb, params[nb], out)
        report(nb.stem, wall, stats, args.top)


if __name__ == "__main__":
    main()
