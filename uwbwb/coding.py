"""Coding exercises of notebooks 01–05: the student writes one equation of the paper as a small function.

Each :class:`Exercise` declares the function the student completes (its signature and docstring: the stub
cell of the notebook is :meth:`Exercise.stub`), the package's own implementation it is checked against
(the function the filter itself calls), a generator of cases, the answer (:meth:`Exercise.answer`, which the
answer key of :mod:`uwbwb.classroom` puts in the stub's place) and *known mistakes*: deliberately wrong
variants, each with what it gets wrong. :func:`check` runs the student's function on the cases and says:

* ``not written yet`` — the stub still raises :class:`NotImplementedError` (the cell does not fail);
* ``wrong`` — an exception, a wrong shape or type, a known mistake (the first variant that matches on every
  case), the negative of the equation, or else where the numbers differ;
* ``right`` — equal to the package's function on every case.

Notebook, function and reference (the package's function the filter of the notebook's "in a cell" section
calls): 01 ``fix_log_likelihood``, :func:`uwbwb.models.setnoise.log_likelihood` (eq. 9, in ``pf_update``);
02 ``range_residuals``, :meth:`uwbwb.models.track.LinearTrackRanges.residuals_jacobian` (eq. 1); 03
``tdoa_jacobian``, :meth:`uwbwb.models.tdoa.TdoaModel.jacobian` (the EKF's ``H``); 04 ``delta_p``,
:meth:`uwbwb.models.doppler.DopplerModel.delta_p` (eq 1); 05 ``eq4_outliers``,
:func:`uwbwb.models.tdoa.triangle_outliers` (eq. 4, in ``TdoaUpdate``).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .models.doppler import DopplerModel
from .models.setnoise import log_likelihood
from .models.tdoa import TdoaModel, triangle_outliers
from .models.track import LinearTrackRanges
from .types import Anchors

__all__ = ["EXERCISES", "EXERCISE_TAG", "STUB_BODY", "Exercise", "Verdict", "answer_cell", "check", "exercise_of"]

#: Tag of a notebook's stub cell (the answer key replaces its body by the answer; it may define a function).
EXERCISE_TAG = "coding-exercise"
#: The body of every stub: what the student replaces.
STUB_BODY = 'raise NotImplementedError("your code")'


@dataclass(frozen=True)
class Exercise:
    """One coding exercise (module docstring). ``mistakes`` are ``(what is wrong, variant)`` pairs; a variant
    takes the student's arguments. ``shape_hint`` is said with a wrong shape."""

    notebook: str
    name: str
    signature: str
    doc: str
    answer_body: str
    reference: Callable
    cases: Callable[[np.random.Generator], list[tuple]]
    mistakes: tuple[tuple[str, Callable], ...]
    shape_hint: str

    def _source(self, body: str) -> str:
        return f'def {self.name}({self.signature}):\n    """{self.doc}"""\n' + "".join(
            f"    {line}\n" for line in body.splitlines())

    def stub(self) -> str:
        """The source of the stub cell."""
        return self._source(STUB_BODY).rstrip("\n")

    def answer(self) -> str:
        """The stub with its body written: the answer key's cell."""
        return self._source(self.answer_body).rstrip("\n")

    def solved(self) -> Callable:
        """The answer as a function."""
        space = {"np": np}
        exec(self.answer(), space)
        return space[self.name]


@dataclass(frozen=True)
class Verdict:
    """What :func:`check` found: ``status`` is ``"right"``, ``"wrong"`` or ``"not written yet"``."""

    name: str
    status: str
    message: str

    @property
    def right(self) -> bool:
        return self.status == "right"

    def __str__(self) -> str:
        return f"{self.name}: {self.status} — {self.message}"

    def _repr_markdown_(self) -> str:
        mark = {"right": "✔", "wrong": "✘"}.get(self.status, "…")
        return f"**{mark} `{self.name}`: {self.status}.** {self.message}"


def _same(a, b) -> bool:
    if a.dtype == bool or b.dtype == bool:
        return a.dtype == b.dtype and np.array_equal(a, b)
    return bool(np.allclose(a, b, rtol=1e-7, atol=1e-12 * max(1.0, float(np.max(np.abs(b), initial=0.0)))))


def check(student: Callable) -> Verdict:
    """Run ``student`` against its exercise (found by the function's ``__name__``) on the exercise's cases, drawn
    with seed 0, and say what is wrong (module docstring)."""
    ex = exercise_of(getattr(student, "__name__", ""))
    cases = ex.cases(np.random.default_rng(0))
    expected = [np.asarray(ex.reference(*c)) for c in cases]
    got = []
    for i, case in enumerate(cases):
        try:
            got.append(np.asarray(student(*(np.copy(a) if isinstance(a, np.ndarray) else a for a in case))))
        except NotImplementedError:
            return Verdict(ex.name, "not written yet", "replace the `raise NotImplementedError` line by your code "
                                                       "and run both cells again.")
        except Exception as exc:  # the student's error, reported instead of raised
            return Verdict(ex.name, "wrong", f"case {i + 1} raises {type(exc).__name__}: {exc}")
    for i, (g, e) in enumerate(zip(got, expected)):
        if g.shape != e.shape:
            return Verdict(ex.name, "wrong", f"wrong shape: {g.shape} in case {i + 1}, expected {e.shape} "
                                             f"— {ex.shape_hint}")
        if (e.dtype == bool) != (g.dtype == bool):
            return Verdict(ex.name, "wrong", f"wrong type: {g.dtype} values, expected {e.dtype}.")
    if all(_same(g, e) for g, e in zip(got, expected)):
        return Verdict(ex.name, "right", f"equal to the package's own on all {len(cases)} cases.")
    for what, variant in ex.mistakes:
        if all(_same(g, np.asarray(variant(*c))) for g, c in zip(got, cases)):
            return Verdict(ex.name, "wrong", what)
    if all(e.dtype != bool and _same(g, -e) for g, e in zip(got, expected)):
        return Verdict(ex.name, "wrong", "wrong sign: your result is the negative of the equation's.")
    i = next(k for k, (g, e) in enumerate(zip(got, expected)) if not _same(g, e))
    return Verdict(ex.name, "wrong", f"wrong values in case {i + 1}: got {np.round(got[i], 6).tolist()}, "
                                     f"expected {np.round(expected[i], 6).tolist()}.")


def exercise_of(name: str) -> Exercise:
    """The exercise of a function name or a notebook number (``"01"``)."""
    for ex in EXERCISES:
        if name in (ex.name, ex.notebook):
            return ex
    raise KeyError(f"no coding exercise {name!r}; there are {[ex.name for ex in EXERCISES]}")


def answer_cell(source: str) -> str:
    """The answer key's source of a stub cell (tagged :data:`EXERCISE_TAG`): the answer of the exercise whose
    function the cell defines."""
    m = re.search(r"^def\s+(\w+)\s*\(", source, flags=re.M)
    if m is None:
        raise ValueError(f"a cell tagged {EXERCISE_TAG!r} defines no function:\n{source}")
    return exercise_of(m.group(1)).answer()


# ---------------------------------------------------------------- the five exercises

def _box(rng, n, size=(10.0, 8.0, 3.0)):
    return rng.uniform(0.0, 1.0, (n, 3)) * size


def _setnoise_cases(rng):
    return [(rng.normal(0, 0.5, (6, 2)), rng.normal(0, 0.5, 2), rng.normal(0, 0.2, 2), rng.uniform(0.03, 0.4, 2))
            for _ in range(3)]


def _nls_cases(rng):
    out = []
    for m in (5, 8):
        t = np.sort(rng.uniform(0, 4, m))
        anchors = _box(rng, m)
        out.append((rng.uniform(2, 6, 3), rng.normal(0, 0.8, 3), t, anchors,
                    rng.uniform(1, 8, m)))
    return out


def _tdoa_cases(rng):
    return [(_box(rng, 1)[0], _box(rng, n), int(rng.integers(n))) for n in (4, 6)]


def _doppler_cases(rng):
    return [(_box(rng, 1)[0] - 5, rng.normal(0, 1.5, 3), _box(rng, n) - 5, 0.501 + 0.006 * np.arange(n), 343.2)
            for n in (4, 8)]


def _eq4_cases(rng):
    out = []
    for n in (5, 6, 8):
        anchors, ref = _box(rng, n), int(rng.integers(n))
        base = np.linalg.norm(anchors - anchors[ref], axis=1)
        tdoa = base * rng.choice([-1, 1], n) * rng.uniform(0.85, 1.05, n)
        tdoa[ref], tdoa[(ref + 1) % n] = 0.0, np.nan
        out.append((tdoa, ref, anchors, 0.3))
    return out


def _nls_ref(P, v, t, anchors, d):
    track = LinearTrackRanges(anchors)
    return track.residuals_jacobian(track.pack(P, v), t, np.arange(len(t)), d, jacobian=False)[0]


def _dp_ref(pos, vel, beacons, period, v_s):
    return DopplerModel(Anchors(tuple(map(str, range(len(beacons)))), beacons), period, v_s).delta_p(pos, vel)


def _r(pos, vel, beacons, v_s, unit=True):
    d = pos - beacons
    return (d @ vel) / (v_s * (np.linalg.norm(d, axis=1) if unit else 1.0))


def _eq4(d, ref, a, c, *, absolute=True, c_sign=-1, keep_ref=False):
    bad = (np.abs(d) if absolute else d) > np.linalg.norm(a - a[ref], axis=1) + c_sign * c
    if not keep_ref:
        bad[ref] = False
    return bad


_INVERTED = "inverted: True marks a TDoA that FAILS eq. 4 (an outlier), not one that passes."

EXERCISES: tuple[Exercise, ...] = (
    Exercise("01", "fix_log_likelihood", "pos_m, z_m, mu_m, sigma_m",
             "Eq. 9 in logs: pos_m (K, 2) particles; z_m, mu_m, sigma_m (2,) fix, set bias, set spread -> (K,).",
             "r = (pos_m + mu_m - z_m) / sigma_m\nreturn -0.5 * np.sum(r ** 2, axis=-1)",
             log_likelihood, _setnoise_cases,
             (("the bias enters with eq. 9's printed sign (x − μ − x̃): a particle's expected fix is x + μ (eq. 6), "
               "so the residual is x + μ − x̃.", lambda p, z, mu, s: -0.5 * np.sum(((p - mu - z) / s) ** 2, -1)),
              ("missing σ: divide each axis' residual by its own σ before squaring.",
               lambda p, z, mu, s: -0.5 * np.sum((p + mu - z) ** 2, -1)),
              ("divided by σ, not σ²: it is the normalised residual r = (x + μ − x̃)/σ that is squared.",
               lambda p, z, mu, s: -0.5 * np.sum((p + mu - z) ** 2 / s, -1)),
              ("missing the factor ½ of the Gaussian exponent.",
               lambda p, z, mu, s: -np.sum(((p + mu - z) / s) ** 2, -1)),
              ("wrong sign: a log-likelihood is −½ Σ r²; yours favours particles far from the fix.",
               lambda p, z, mu, s: 0.5 * np.sum(((p + mu - z) / s) ** 2, -1))),
             "one log-likelihood per particle: sum the x and y terms (axis=-1)."),
    Exercise("02", "range_residuals", "P_m, v_mps, t_s, anchors_m, range_m",
             "Eq. 1 residuals: P_m, v_mps (3,); t_s, range_m (M,); anchors_m (M, 3), each range's anchor -> (M,).",
             "diff = P_m + np.outer(t_s, v_mps) - anchors_m\nreturn np.linalg.norm(diff, axis=1) - range_m",
             _nls_ref, _nls_cases,
             (("missing the motion term v t_m: at time t_m the node is at P + v t_m.",
               lambda P, v, t, a, d: np.linalg.norm(P - a, axis=1) - d),
              ("v t_m subtracted: the node moves forward, P + v t_m.",
               lambda P, v, t, a, d: np.linalg.norm(P - np.outer(t, v) - a, axis=1) - d),
              ("squared ranges (‖·‖² − d²) are not eq. 1's residual: they weight long ranges more.",
               lambda P, v, t, a, d: np.sum((P + np.outer(t, v) - a) ** 2, axis=1) - d ** 2),
              ("wrong sign: eq. 1's residual is predicted minus measured, ‖P + v t_m − P_k‖ − d.",
               lambda P, v, t, a, d: d - np.linalg.norm(P + np.outer(t, v) - a, axis=1))),
             "one residual per range (not their sum of squares)."),
    Exercise("03", "tdoa_jacobian", "pos_m, anchors_m, ref",
             "Rows u_j - u_ref of dh/dp: tag pos_m (3,), anchors_m (n, 3), reference index ref -> (n, 3).",
             "d = pos_m - anchors_m\nu = d / np.linalg.norm(d, axis=1, keepdims=True)\nreturn u - u[ref]",
             lambda p, a, ref: TdoaModel(a, dim=3).jacobian(p, ref), _tdoa_cases,
             (("missing − u_ref: h_j = r_j − r_ref, and the reference range moves with p too.",
               lambda p, a, ref: (p - a) / np.linalg.norm(p - a, axis=1, keepdims=True)),
              ("not unit vectors: divide p − a_j by its length ‖p − a_j‖.", lambda p, a, ref: (p - a) - (p - a[ref])),
              ("wrong sign: u_j = (p − a_j)/‖p − a_j‖ points from the anchor to the tag; yours is its negative.",
               lambda p, a, ref: -TdoaModel(a, dim=3).jacobian(p, ref))),
             "one row per anchor, the reference's row zero."),
    Exercise("04", "delta_p", "pos_m, vel_mps, beacons_m, period_s, v_s_mps",
             "Eq 1: pos_m, vel_mps (3,) receiver; beacons_m (n, 3); period_s (n,); v_s_mps -> ΔP (n,), seconds.",
             "d = pos_m - beacons_m\nr = (d @ vel_mps) / (np.linalg.norm(d, axis=1) * v_s_mps)\n"
             "return period_s * r / (1 - r)",
             _dp_ref, _doppler_cases,
             (("first order only: P r drops eq 1's 1/(1 − r).", lambda X, V, T, P, vs: P * _r(X, V, T, vs)),
              ("u points from the receiver to the beacon: eq 1's u = (X − T)/‖X − T‖ (moving away lengthens P).",
               lambda X, V, T, P, vs: -P * _r(X, V, T, vs) / (1 + _r(X, V, T, vs))),
              ("1 + r in the denominator: from ΔP v_s/(P + ΔP) = u·V, ΔP = P r/(1 − r).",
               lambda X, V, T, P, vs: P * _r(X, V, T, vs) / (1 + _r(X, V, T, vs))),
              ("u is not a unit vector: divide X − T by ‖X − T‖.",
               lambda X, V, T, P, vs: P * _r(X, V, T, vs, False) / (1 - _r(X, V, T, vs, False)))),
             "one ΔP per beacon."),
    Exercise("05", "eq4_outliers", "tdoa_m, ref, anchors_m, c_m",
             "Eq. 4: True where |L_j| > ||P_j - P_ref|| - C; tdoa_m (n,), 0 at ref, NaN if missing -> bool (n,).",
             "bad = np.abs(tdoa_m) > np.linalg.norm(anchors_m - anchors_m[ref], axis=1) - c_m\n"
             "bad[ref] = False          # the reference is no measurement\nreturn bad",
             triangle_outliers, _eq4_cases,
             (("missing |L|: a TDoA may be negative; eq. 4 bounds its magnitude.",
               lambda *c: _eq4(*c, absolute=False)),
              ("C added: eq. 4 keeps a TDoA only up to C *inside* the baseline, ‖P_1 − P_2‖ − C.",
               lambda *c: _eq4(*c, c_sign=1)),
              ("the reference anchor is flagged: its 0 is no measurement (set it False).",
               lambda *c: _eq4(*c, keep_ref=True)),
              (_INVERTED, lambda d, ref, a, c: ~_eq4(np.where(np.isnan(d), np.inf, d), ref, a, c, keep_ref=True)),
              (_INVERTED, lambda *c: ~triangle_outliers(*c))),
             "one True/False per anchor."),
)
