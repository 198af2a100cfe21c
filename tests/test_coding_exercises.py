"""The coding exercises of notebooks 01–05 (:mod:`uwbwb.coding`): a right, a wrong and a missing answer each,
the notebooks' stub cells, and the answer key that fills them in."""

from __future__ import annotations

import json
from pathlib import Path

import nbformat
import numpy as np
import pytest

from uwbwb import classroom, coding

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"
NAMES = [ex.name for ex in coding.EXERCISES]


def _as(name, fn):
    """``fn`` under the student's function name (check finds the exercise by it)."""
    fn.__name__ = name
    return fn


@pytest.mark.parametrize("name", NAMES)
def test_the_answer_is_right_and_the_stub_is_not_written_yet(name):
    ex = coding.exercise_of(name)
    verdict = coding.check(ex.solved())
    assert verdict.status == "right" and verdict.right, verdict
    space = {"np": np}
    exec(ex.stub(), space)                                   # the stub cell as the student gets it
    verdict = coding.check(space[name])
    assert verdict.status == "not written yet" and not verdict.right, verdict


@pytest.mark.parametrize("name, index", [(ex.name, i) for ex in coding.EXERCISES for i in range(len(ex.mistakes))])
def test_each_known_mistake_gets_its_own_diagnosis(name, index):
    ex = coding.exercise_of(name)
    what, variant = ex.mistakes[index]
    verdict = coding.check(_as(name, lambda *a: variant(*a)))
    assert verdict.status == "wrong" and verdict.message == what


@pytest.mark.parametrize("name", NAMES)
def test_a_wrong_shape_is_named_with_the_expected_shape(name):
    ex = coding.exercise_of(name)
    answer = ex.solved()
    verdict = coding.check(_as(name, lambda *a: np.atleast_1d(answer(*a))[:-1]))
    assert verdict.status == "wrong" and verdict.message.startswith("wrong shape") and ex.shape_hint in verdict.message


@pytest.mark.parametrize("name", ["range_residuals", "tdoa_jacobian", "delta_p"])
def test_a_flipped_sign_is_named(name):
    answer = coding.exercise_of(name).solved()
    verdict = coding.check(_as(name, lambda *a: -answer(*a)))
    assert verdict.status == "wrong" and "sign" in verdict.message, verdict


def test_a_flipped_sign_without_a_declared_message_is_found_generically():
    answer = coding.exercise_of("delta_p").solved()
    verdict = coding.check(_as("delta_p", lambda *a: -answer(*a)))
    assert verdict.message == "wrong sign: your result is the negative of the equation's."


def test_other_wrong_answers_say_where_and_errors_are_reported_not_raised():
    answer = coding.exercise_of("fix_log_likelihood").solved()
    verdict = coding.check(_as("fix_log_likelihood", lambda *a: answer(*a) + 1e-3))
    assert verdict.status == "wrong" and verdict.message.startswith("wrong values in case 1")
    verdict = coding.check(_as("delta_p", lambda *a: 1 / 0))
    assert verdict.status == "wrong" and "ZeroDivisionError" in verdict.message
    verdict = coding.check(_as("eq4_outliers", lambda *a: coding.exercise_of("05").solved()(*a).astype(float)))
    assert verdict.message.startswith("wrong type")


def test_the_student_cannot_change_the_cases():
    answer = coding.exercise_of("eq4_outliers").solved()

    def eq4_outliers(tdoa_m, ref, anchors_m, c_m):
        out = answer(tdoa_m, ref, anchors_m, c_m)
        tdoa_m[:] = 0.0                                      # mutates its input after answering
        return out

    assert coding.check(eq4_outliers).right


def test_the_variants_are_distinct_from_the_reference():
    # a variant equal to the reference on every case would make its diagnosis unreachable
    for ex in coding.EXERCISES:
        cases = ex.cases(np.random.default_rng(0))
        for what, variant in ex.mistakes:
            assert any(not np.array_equal(np.asarray(variant(*c)), np.asarray(ex.reference(*c)), equal_nan=True)
                       for c in cases), (ex.name, what)


def test_unknown_exercises_are_refused():
    with pytest.raises(KeyError, match="no coding exercise"):
        coding.check(lambda: None)


def _stub_cells(path):
    nb = json.loads(path.read_text(encoding="utf-8"))
    return [c for c in nb["cells"] if coding.EXERCISE_TAG in c.get("metadata", {}).get("tags", [])], nb


@pytest.mark.parametrize("ex", coding.EXERCISES, ids=NAMES)
def test_each_notebook_holds_its_stub_and_its_check(ex):
    path = next(NOTEBOOKS.glob(f"{ex.notebook}_*.ipynb"))
    stubs, nb = _stub_cells(path)
    assert ["".join(c["source"]) for c in stubs] == [ex.stub()]
    sources = ["".join(c["source"]) for c in nb["cells"]]
    k = sources.index(ex.stub())
    assert f"uw.coding.check({ex.name})" in sources[k + 1]
    assert nb["cells"][k - 1]["cell_type"] == "markdown" and f"`{ex.name}(" in sources[k - 1]


def test_the_answer_key_fills_in_the_stubs_and_code_rules_allow_them():
    ex = coding.exercise_of("tdoa_jacobian")
    stub = nbformat.v4.new_code_cell(ex.stub())
    stub.metadata["tags"] = [coding.EXERCISE_TAG]
    other = nbformat.v4.new_code_cell("def helper(x):\n    return x")
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_markdown_cell("front"), stub, other]
    key = classroom.answer_key(nb)
    assert key.cells[1].source == ex.answer() and coding.STUB_BODY not in key.cells[1].source
    assert nb.cells[1].source == ex.stub() and key.cells[2].source == other.source     # nothing else changes
    assert classroom.code_rules(nb) == ["cell 2: defines a function (move it into the experiment package)"]
    stub.source = "x = 1"
    with pytest.raises(ValueError, match="defines no function"):
        classroom.answer_key(nb)
