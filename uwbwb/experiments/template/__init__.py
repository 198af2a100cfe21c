"""The template experiment package: copy it to add a method or a paper.

A tiny but complete study — range multilateration (LS) against the package's TDoA EKF on a short
simulated walk — laid out the way every experiment package is:

* ``study`` — what the notebook runs: the settings (a frozen :class:`~.study.Config`, FAST and full),
  the data (:func:`~.study.simulate`), the estimators (built from ``filters/``, each returning
  :class:`~uwbwb.types.Estimates`), and the one :class:`~.study.Results` the other modules read;
* ``facts`` — :func:`~.facts.facts` (numbers and verdicts, each from a stated rule on an interval);
* ``headlines`` — the summary rows as data (quantity, unit, kind, paper value) and
  :func:`~.headlines.checks` ``(results, fast)``, which returns what fails;
* ``figures`` — the figures (``ax=`` in, Axes out).

``tests/experiments/test_template.py`` shows what each piece is held to: every check failing on a
doctored result, the verdict flipping across its threshold, same seed same numbers. To add a method:
copy the folder to ``experiments/<name>/``, copy the test, replace ``simulate`` and ``run_estimators``,
declare the new rows and checks, and list the package in README.md and docs/ANATOMY.md.

In a notebook::

    from uwbwb.experiments import template as tp
    res = tp.run_study(fast=FAST, seed=SEED)
    assert not tp.checks(res, FAST), tp.checks(res, FAST)
    f = tp.facts.facts(res)
    for h in tp.HEADLINES:
        summary.add(**h.row(f))     # summary = uw.metrics.Summary(<notebook>, fast=FAST)
"""

from . import facts, figures, headlines, study
from .headlines import HEADLINES, checks
from .study import FAST, FULL, METHODS, Config, Results, run_study

__all__ = ["Config", "FAST", "FULL", "HEADLINES", "METHODS", "Results", "checks", "facts", "figures", "headlines",
           "run_study", "study"]
