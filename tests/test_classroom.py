"""Class mode and the notebook audits (:mod:`uwbwb.classroom`) on small synthetic notebooks and figures."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import nbformat  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from uwbwb import classroom  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _md(text, *tags):
    cell = nbformat.v4.new_markdown_cell(text)
    cell.metadata["tags"] = list(tags)
    return cell


def _code(source="x", *tags, outputs=(), count=None):
    cell = nbformat.v4.new_code_cell(source)
    cell.metadata["tags"] = list(tags)
    cell.outputs = [nbformat.from_dict(o) for o in outputs]
    cell.execution_count = count
    return cell


def _stream(text):
    return {"output_type": "stream", "name": "stdout", "text": text}


def _display(data):
    return {"output_type": "display_data", "data": data, "metadata": {}}


def _html_table(rows):
    body = "".join(f"<tr><td>{i}</td></tr>" for i in range(rows))
    return {"text/html": f"<table><thead><tr><th>a</th></tr></thead><tbody>{body}</tbody></table>",
            "text/plain": "a table"}


def _notebook(*cells):
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    nb.cells = list(cells)
    return nb


def words(n):
    return " ".join(["word"] * n)


# ------------------------------------------------------------------ class limits

def test_class_limits_pass_a_short_notebook():
    nb = _notebook(_md(words(150)), _code(outputs=[_stream(words(200)), _display(_html_table(25))]),
                   _md(words(200)))
    assert classroom.class_limits(nb) == []


def test_class_limits_name_the_cell_and_what_exceeded():
    nb = _notebook(_md(words(151)), _code(outputs=[_stream(words(201))]), _md(words(201)),
                   _code(outputs=[_display(_html_table(26))]),
                   _code(outputs=[_display({"text/markdown": words(120)}), _stream(words(90))]))
    problems = classroom.class_limits(nb)
    assert problems == ["cell 0: markdown of 151 words (limit 150, teaching front)",
                        "cell 1: 201 words of printed output (limit 200)",
                        "cell 2: markdown of 201 words (limit 200)",
                        "cell 3: table of 26 rows (limit 25)",
                        "cell 4: 210 words of printed output (limit 200)"]


def test_class_limits_skip_research_cells_and_count_source_cells():
    injected = _code("FAST = True", "injected-parameters")
    nb = _notebook(_md("front"), injected, _md(words(500), "research"), _code(outputs=[_stream(words(500))]),
                   _code("x", "research", outputs=[_display(_html_table(100))]))
    # the injected cell is not a cell of the notebook: the printing cell is source cell 2
    assert classroom.class_limits(nb) == ["cell 2: 500 words of printed output (limit 200)"]


def test_math_and_link_targets_are_not_prose():
    text = "$$x = " + " + ".join(["a"] * 300) + "$$ see [EKF](GLOSSARY.md#ekf) and $y + z$ — end"
    assert classroom._prose_words(text) == 4          # see, [EKF], and, end


def test_a_long_text_table_counts_as_a_table_not_as_prose():
    table = "\n".join(["    a    b"] + [f"{i}  1.0  2.0" for i in range(30)])
    nb = _notebook(_md("front"), _code(outputs=[{"output_type": "execute_result", "execution_count": 1,
                                                 "data": {"text/plain": table}, "metadata": {}}]))
    assert classroom.class_limits(nb) == ["cell 1: text table of 30 rows (limit 25)"]


# ------------------------------------------------------------------ code rules

def test_code_rules():
    long = "\n".join(f"x{i} = {i}" for i in range(21))
    nb = _notebook(_md("front"), _code("import uwbwb as uw\nuw.metrics.cep50(e)"), _code(long),
                   _code("def f(x):\n    return x"), _code("study._kf_prior(x)\nobj.__class__"),
                   _code("def render(v):\n    return v\n" + long + "\npanel = uw.widgets.Panel('p', {}, render)"))
    assert classroom.code_rules(nb) == ["cell 2: 21 lines of code (limit 20)",
                                        "cell 3: defines a function (move it into the experiment package)",
                                        "cell 4: private name '_kf_prior'"]   # the last, widget cell may do both


# ------------------------------------------------------------------ figure audit rule

def _problems(ax):
    return classroom.axes_problems(classroom.axes_record(ax))


def test_a_labelled_axes_passes():
    _, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set(title="track", xlabel="x (m)", ylabel="error [cm]")
    assert _problems(ax) == []


@pytest.mark.parametrize("xlabel,ok", [("x (m)", True), ("σ_d [cm/s]", True), ("ratio [-]", True),
                                       ("number of particles K", True), ("fraction of epochs", True),
                                       ("x", False), ("particles K", False), ("", False)])
def test_units_rule(xlabel, ok):
    _, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set(title="t", xlabel=xlabel, ylabel="y (m)")
    assert (_problems(ax) == []) is ok, _problems(ax)


def test_what_an_axes_lacks_is_named():
    _, ax = plt.subplots()
    assert _problems(ax) == ["no title or panel label", "no x label", "no y label", "empty panel without a note"]
    ax.text(0.5, 0.5, "(b) no data in this window", transform=ax.transAxes)
    ax.set(xlabel="t (s)", ylabel="v (m/s)")
    assert _problems(ax) == []                          # a panel label, and a note saying why it is empty


def test_shared_and_categorical_axes():
    fig, axes = plt.subplots(2, 1, sharex=True)
    for ax, title in zip(axes, "ab"):
        ax.plot([0, 1], [0, 1])
        ax.set(title=title, ylabel="y (m)")
    axes[1].set_xlabel("t (s)")                         # the upper panel shares the lower one's x label
    assert _problems(axes[0]) == [] and _problems(axes[1]) == []
    _, ax = plt.subplots()
    ax.bar(["{1,2,3}", "{2,3,4}"], [3, 1])
    ax.set(title="sets", xlabel="sensor set", ylabel="fixes")
    assert _problems(ax) == ["y label 'fixes' has no unit"]   # a categorical x needs no unit, the counts do
    _, ax = plt.subplots()
    ax.bar(range(2), [3, 1])
    ax.set_xticks(range(2), ["54321", "{2,3,4}"])                  # fixed ticks labelled with set names
    ax.set(title="sets", xlabel="sensor set", ylabel="number of fixes")
    assert _problems(ax) == []
    ax.set_xticks(range(2), ["0", "1"])                           # fixed ticks labelled with numbers
    assert _problems(ax) == ["x label 'sensor set' has no unit"]


def test_exempt_axes():
    fig, axes = plt.subplots(1, 3)
    axes[0].axis("off")
    im = axes[1].imshow(np.eye(3))
    axes[1].set(title="image", xlabel="column (px)", ylabel="row (px)")
    cbar = fig.colorbar(im, ax=axes[1])
    axes[2].set_visible(False)
    assert _problems(axes[0]) == [] and _problems(cbar.ax) == [] and _problems(axes[2]) == []
    polar = plt.figure().add_subplot(projection="polar")
    polar.plot([0, 1], [1, 2])
    polar.set_title("range error")
    assert _problems(polar) == ["no radial unit (y label or title)"]
    polar.set_title("range error (m)")
    assert _problems(polar) == []


def test_figure_audit_maps_cells_and_counts_images():
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    records = [{"execution_count": 3, "figure": 0, "title": "", "axes": [classroom.axes_record(ax)]}]
    png = _display({"image/png": "iVBOR", "text/plain": "<Figure>"})
    nb = _notebook(_code("hook", classroom.AUDIT_HOOK_TAG, count=1), _md("front"),
                   _code("p", "parameters", count=2), _code("FAST = True", "injected-parameters", count=3 - 1),
                   _code("plot", outputs=[png], count=3))
    problems = classroom.figure_audit(records, nb)
    assert problems == ["cell 2, figure 0, axes 0 ('untitled'): no title or panel label",
                        "cell 2, figure 0, axes 0 ('untitled'): no x label",
                        "cell 2, figure 0, axes 0 ('untitled'): no y label"]
    assert classroom.figure_audit([], nb) == [
        "the recorder saw none of the figures (was rcParams['figure.hooks'] reset?): nothing audited"]
    nb.cells[-1].outputs = []
    assert classroom.figure_audit([], nb) == ["no image output: the HTML report would hold no figure"]


# ------------------------------------------------------------------ folding and handouts

def test_research_cells_fold_and_leave_the_handout():
    nb = _notebook(_md("# Front"), _code("print('kept')", outputs=[_stream("kept output\n")]),
                   _code("print('bookkeeping')", "research", outputs=[_stream("RESEARCH OUTPUT\n")]),
                   _md("RESEARCH NOTES", "research"))
    classroom.fold_research(nb)
    assert nb.cells[2].metadata["jupyter"] == {"source_hidden": True, "outputs_hidden": True}
    assert "jupyter" not in nb.cells[1].metadata
    html = classroom.handout_html(nb)
    assert "kept output" in html and "RESEARCH OUTPUT" not in html and "RESEARCH NOTES" not in html


# ------------------------------------------------------------------ execution (a kernel each)

_FIGURE_CELL = ("import matplotlib.pyplot as plt\nfig, axes = plt.subplots(1, 2)\naxes[0].plot([0, 1])\n"
                "axes[0].set(title='good', xlabel='t (s)', ylabel='x (m)')\naxes[1].set_title('empty')\n"
                "plt.close(fig)")


@pytest.mark.notebook
def test_recorder_sees_axes_of_figures_closed_by_the_cell(tmp_path):
    """The hook records every pyplot figure of the run, even one the cell itself closes."""
    import papermill as pm

    records = tmp_path / "figures.json"
    nb = _notebook(_md("front"), _code("FAST = False", "parameters"), _code("%matplotlib inline"),
                   _code(_FIGURE_CELL))
    nb.cells.insert(0, classroom.hook_cell(records))
    nbformat.write(nb, tmp_path / "in.ipynb")
    pm.execute_notebook(str(tmp_path / "in.ipynb"), str(tmp_path / "out.ipynb"), parameters={"FAST": True},
                        kernel_name="python3", progress_bar=False)
    executed = nbformat.read(tmp_path / "out.ipynb", as_version=4)
    problems = classroom.figure_audit(json.loads(records.read_text()), executed)
    assert problems == ["cell 3, figure 0, axes 1 ('empty'): no x label",
                        "cell 3, figure 0, axes 1 ('empty'): no y label",
                        "cell 3, figure 0, axes 1 ('empty'): empty panel without a note",
                        "no image output: the HTML report would hold no figure"]


@pytest.mark.notebook
def test_class_run_writes_folded_notebooks_and_handouts(tmp_path, capfd):
    src = tmp_path / "notebooks"
    src.mkdir()
    nb = _notebook(_md("# Lab"), _code("FAST = False\nCLASS = False", "parameters"),
                   _code("print('mode', FAST, CLASS)"),
                   _code("print('bookkeeping ' * 300)", "research"))
    nbformat.write(nb, src / "00_lab.ipynb")
    broken = _notebook(_md("# Broken"), _code("FAST = False", "parameters"), _code("1 / 0"))
    nbformat.write(broken, src / "01_broken.ipynb")
    out = tmp_path / "class"
    out.mkdir()
    assert classroom.main(["--only", "00", "--notebooks-dir", str(src), "--out", str(out)]) == 0
    executed = nbformat.read(out / "answers" / "00_lab.ipynb", as_version=4)
    assert "mode True True" in executed.cells[2].outputs[0]["text"]          # FAST and CLASS in the cell itself
    assert executed.cells[3].metadata["jupyter"]["outputs_hidden"] is True    # research folded ...
    html = (out / "answers" / "00_lab.html").read_text()
    assert "mode True True" in html and "bookkeeping" not in html             # ... and not in the handout
    printed = capfd.readouterr()          # the kernel's own output too: it runs on IPC, no TCP warning
    assert "00_lab: ok in" in printed.out and "01_broken" not in printed.out
    assert "without encryption" not in printed.out + printed.err
    # a notebook without CLASS runs FAST only and says so; an execution error gives a non-zero exit
    assert classroom.main(["--only", "01", "--notebooks-dir", str(src), "--out", str(out)]) == 1
    printed = capfd.readouterr().out
    assert "01_broken: FAILED" in printed and "no CLASS parameter" in printed and "ZeroDivisionError" in printed


@pytest.mark.parametrize("argv, message", [(["--timeout", "0"], "--timeout must be a positive"),
                                           (["--timeout", "-1"], "--timeout must be a positive"),
                                           (["--timeout", "nan"], "--timeout must be a positive"),
                                           (["--out", "FILE"], "exists and is not a folder")])
def test_class_mode_refuses_arguments_it_cannot_use(argv, message, tmp_path, capsys):
    (tmp_path / "FILE").write_text("x")
    argv = [str(tmp_path / a) if a == "FILE" else a for a in argv]
    with pytest.raises(SystemExit) as exc:
        classroom.main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err


def test_class_mode_writes_into_the_working_directory_by_default():
    assert not classroom.CLASS_DIR.is_absolute()          # never beside the installed package


def test_a_table_pandas_cut_is_named_and_a_whole_one_is_not():
    import pandas as pd

    wide = pd.DataFrame([range(30)], columns=[f"c{i}" for i in range(30)])
    with pd.option_context("display.max_columns", 20):
        cut = {"text/html": wide._repr_html_(), "text/plain": repr(wide)}
    with pd.option_context("display.max_columns", None):
        whole = {"text/html": wide._repr_html_(), "text/plain": repr(wide)}
    research = _code(outputs=[_display(cut)])
    research.metadata["tags"] = ["research"]
    nb = _notebook(_md("front"), _code(outputs=[_display(whole)]), research)
    assert classroom.cut_tables(nb) == ["cell 2: a table printed with columns hidden (1 rows × 30 columns)"]
    assert classroom.cut_tables(_notebook(_md("front"), _code(outputs=[_display(whole)]))) == []
    long = pd.DataFrame({"a": range(200), "b": range(200)})
    with pd.option_context("display.max_columns", None):
        rows_cut = {"text/html": long._repr_html_(), "text/plain": repr(long)}
    assert "200 rows" in rows_cut["text/html"]
    assert classroom.cut_tables(_notebook(_md("front"), _code(outputs=[_display(rows_cut)]))) == []   # head and tail
    plain = _notebook(_md("front"), _code(outputs=[_display({"text/plain": cut["text/plain"]})]))
    assert classroom.cut_tables(plain) == ["cell 1: a table printed with columns hidden (1 rows × 30 columns)"]


def test_the_answer_key_writes_the_claim_and_a_check_that_disagrees_is_named():
    from uwbwb.widgets import ExerciseCheck

    pred = _code('PREDICTION_1 = None  # write "not up" or "up": the error', "prediction")
    pred.metadata[classroom.CLAIM_KEY] = "up"                                   # the claim, second in the line
    nb = _notebook(_md("front"), pred, _code("check.against(PREDICTION_1, reveal=not CLASS)"))
    key = classroom.answer_key(nb)
    assert key.cells[1].source == 'PREDICTION_1 = "up"  # write "not up" or "up": the error'
    assert nb.cells[1].source.startswith("PREDICTION_1 = None")                 # the student's copy is unchanged
    student = classroom.student_notebook(nb, {})
    assert classroom.CLAIM_KEY not in student.cells[1].metadata                 # nothing in it names the claim
    assert classroom.answer_key(student, classroom.prediction_claims(nb)).cells[1].source == key.cells[1].source
    with pytest.raises(ValueError, match="claim"):
        classroom.answer_key(student)
    for bad, claim in (("PREDICTION_1 = 'up'", "up"), ("PREDICTION_1 = None  # up or down", "up"),
                       ('PREDICTION_1 = None  # write "up" or "down"', "sideways"),
                       ('PREDICTION_1 = None  # write "up" or "down"', None)):
        cell = _code(bad, "prediction")
        if claim is not None:
            cell.metadata[classroom.CLAIM_KEY] = claim
        with pytest.raises(ValueError, match="PREDICTION"):
            classroom.answer_key(_notebook(cell))
    # executed: the check's Markdown output says right when the run shows the claim, and not when it does not
    for holds, expected in ((True, []), (False, ['cell 1: PREDICTION_1 = "up" is not what its check shows'])):
        shown = ExerciseCheck("error up", holds, {"e (m)": 1.0}, ("up", "not up")).against("up")
        key.cells[2].outputs = [nbformat.from_dict({"output_type": "execute_result", "execution_count": 1,
                                                    "metadata": {}, "data": {"text/markdown": shown._repr_markdown_()}})]
        assert classroom.wrong_predictions(key) == expected
    assert classroom.wrong_predictions(_notebook(key.cells[1])) == ["cell 0: no check cell reads PREDICTION_1"]


def test_the_answer_key_of_a_coding_exercise_must_be_right_by_its_check():
    from uwbwb import coding

    ex = coding.exercise_of("04")
    nb = _notebook(_md("front"), _code(ex.stub(), coding.EXERCISE_TAG), _code("x = 1"),
                   _code(f"uw.coding.check({ex.name})   # yours against DopplerModel.delta_p"))
    key = classroom.answer_key(nb)
    assert key.cells[1].source == ex.answer()
    space = {"np": np}
    exec(ex.stub(), space)
    negated = ex.solved()

    def wrong(*args):
        return -negated(*args)

    wrong.__name__ = ex.name
    said = f"cell 1: the answer of {ex.name} is not right by its check"
    for student, expected in ((ex.solved(), []), (wrong, [said]), (space[ex.name], [said])):   # right, wrong, missing
        verdict = coding.check(student)
        key.cells[3].outputs = [nbformat.from_dict({"output_type": "execute_result", "execution_count": 2,
                                                    "metadata": {}, "data": {"text/markdown": verdict._repr_markdown_(),
                                                                             "text/plain": str(verdict)}})]
        assert classroom.wrong_predictions(key) == expected, verdict
    key.cells[3].outputs = []
    assert classroom.wrong_predictions(key) == [said]                          # a check that did not run
    assert classroom.wrong_predictions(_notebook(key.cells[1])) == [f"cell 0: no check cell reads {ex.name}"]


def test_class_limits_name_an_empty_section_and_a_reference_to_a_research_cell():
    nb = _notebook(_md("front"), _md("See the protocol. Details: next cell."), _md("protocol", "research"),
                   _md("## 2 · Real data"), _code("x", "research"), _md("## 3 · Next"), _code("y"))
    assert classroom.class_limits(nb) == ["cell 1: refers to the next cell, a research cell left out in class",
                                          "cell 3: section '## 2 · Real data' is empty without its research cells"]
    ok = _notebook(_md("front"), _md("Details: next cell."), _code("x"), _md("## 2 · Real data"), _code("x"))
    assert classroom.class_limits(ok) == []
