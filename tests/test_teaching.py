"""The teaching path: glossary coverage, glossary links, teaching fronts and checked exercises.

A notebook listed in :data:`TAUGHT` must link every glossary acronym at its first use, open with a
short teaching front (objectives, prerequisites, run times) and carry at least two exercises, each
followed by a check cell. Every acronym in any notebook's Markdown must have a glossary entry.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK_DIR = ROOT / "notebooks"
GLOSSARY = NOTEBOOK_DIR / "GLOSSARY.md"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))

#: Notebooks that are part of the lab route (TEACHING.md); add a stem here once its front, links and
#: exercises are in place.
TAUGHT = ("00_quickstart", "01_set_noise_pf", "02_pruning_nls", "03_ekf_motion_models", "04_doppler_beacons", "05_uwb_ins_fusion", "06_scoreboard")

#: Capitalised tokens that are names, not acronyms: datasets, labs, conferences, devices, software,
#: degrees, Roman numerals of paper sections.
NOT_ACRONYMS = frozenset({
    "LIAS", "IASL", "LIPS", "ICRA", "EUSIPCO", "IEEE", "MATLAB", "NumPy", "SciPy", "MSc", "PhD", "McCarthy",
    "T4F", "DWM1000", "DWM1001", "UM7", "BS1", "BS2", "BS3", "II", "III", "IV", "VI", "VII", "HTML", "JSON",
})

#: Terms the issue asks the glossary to define (acronyms and workbench words).
REQUIRED = ("NLOS", "LOS", "TDoA", "TWR", "NEES", "NIS", "SCAAT", "PCRLB", "CRLB", "ESKF", "EKF", "PF", "KF",
            "GDOP", "CEP", "ESS", "RMSE", "INS", "IMU", "UWB", "FAST", "coverage", "common epochs", "target",
            "input", "reproduced", "full mode")

_ANCHOR = re.compile(r'<a id="([^"]+)"></a>\s*\n###\s+(.+)')
_TOKEN = re.compile(r"(?<![A-Za-z0-9_\\/#.-])([A-Z][A-Za-z0-9]*[A-Z][A-Za-z0-9]*)(?![A-Za-z0-9_])")
_LINK = re.compile(r"\[([^\]]*)\]\(([^)\s]*)\)")


def glossary() -> dict[str, str]:
    """``{term: anchor id}`` of every glossary entry (``<a id="..."></a>`` then ``### term``)."""
    return {term.strip(): anchor for anchor, term in _ANCHOR.findall(GLOSSARY.read_text(encoding="utf-8"))}


def acronyms(entries: dict[str, str]) -> dict[str, str]:
    """The entries that are acronyms (two or more capitals), ``{acronym: anchor id}``."""
    return {t: a for t, a in entries.items() if _TOKEN.fullmatch(t)}


def _blank(match: re.Match) -> str:
    return " " * len(match.group())


def prose(markdown: str) -> str:
    """``markdown`` with math, code spans, HTML tags and link targets blanked (positions kept)."""
    s = re.sub(r"\$\$.*?\$\$", _blank, markdown, flags=re.S)
    s = re.sub(r"\$[^$\n]*\$", _blank, s)
    s = re.sub(r"```.*?```", _blank, s, flags=re.S)
    s = re.sub(r"`[^`]*`", _blank, s)
    s = re.sub(r"<[^>\n]*>", _blank, s)
    return re.sub(r"\]\([^)\s]*\)", lambda m: "]" + " " * (len(m.group()) - 1), s)


def canonical(token: str, known) -> str | None:
    """The glossary acronym a token stands for: itself, without a plural ``s``, or without a number
    suffix (CEP95 → CEP); None if none is known."""
    for cand in (token, token[:-1] if token.endswith("s") else None, re.sub(r"\d+$", "", token)):
        if cand and cand in known:
            return cand
    return None


def markdown_cells(path: Path) -> list[str]:
    return [c.source for c in nbformat.read(path, as_version=4).cells if c.cell_type == "markdown"]


def first_uses(cells: list[str], known) -> dict[str, tuple[int, int, str]]:
    """``{acronym: (cell index, position, token)}`` of each glossary acronym's first use in prose."""
    out = {}
    for i, text in enumerate(cells):
        for m in _TOKEN.finditer(prose(text)):
            acr = canonical(m.group(1), known)
            if acr is not None and acr not in out:
                out[acr] = (i, m.start(), m.group(1))
    return out


def linked_at(text: str, pos: int, anchor: str) -> bool:
    """Whether position ``pos`` of ``text`` lies in the text of a link to ``GLOSSARY.md#anchor``."""
    return any(m.start(1) <= pos < m.end(1) and m.group(2) == f"GLOSSARY.md#{anchor}" for m in _LINK.finditer(text))


def unlinked(path: Path) -> list[str]:
    """Glossary acronyms whose first use in ``path`` is not a link to their entry."""
    known = acronyms(glossary())
    cells = markdown_cells(path)
    return [f"{tok} (markdown cell {i})" for acr, (i, pos, tok) in first_uses(cells, known).items()
            if not linked_at(cells[i], pos, known[acr])]


# --------------------------------------------------------------------------- glossary

def test_glossary_defines_the_required_terms():
    entries = glossary()
    missing = [t for t in REQUIRED if t not in entries]
    assert not missing, f"{GLOSSARY.name} lacks entries for {missing}"
    ids = list(entries.values())
    assert len(ids) == len(set(ids)), "glossary anchors must be unique"
    text = GLOSSARY.read_text(encoding="utf-8")
    for anchor, term in _ANCHOR.findall(text):
        body = text.split(f'<a id="{anchor}"></a>', 1)[1].split("<a id=", 1)[0]
        assert len(body.split()) > 6, f"glossary entry {term!r} has no definition"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_every_acronym_in_a_notebook_has_a_glossary_entry(path):
    known = acronyms(glossary())
    tokens = {m.group(1) for text in markdown_cells(path) for m in _TOKEN.finditer(prose(text))}
    missing = sorted(t for t in tokens if t not in NOT_ACRONYMS and canonical(t, known) is None)
    assert not missing, (f"{path.name} uses {missing} without an entry in notebooks/GLOSSARY.md "
                         "(add one, or add a proper name to NOT_ACRONYMS in this test)")


def test_glossary_links_resolve():
    ids = set(glossary().values())
    text = GLOSSARY.read_text(encoding="utf-8")
    bad = [t for _, t in _LINK.findall(text) if t.startswith("#") and t[1:] not in ids]
    for stem in TAUGHT:
        bad += [t for text in markdown_cells(NOTEBOOK_DIR / f"{stem}.ipynb") for _, t in _LINK.findall(text)
                if t.startswith("GLOSSARY.md#") and t.split("#", 1)[1] not in ids]
    assert not bad, f"links to missing glossary entries: {bad}"


@pytest.mark.parametrize("stem", TAUGHT)
def test_taught_notebook_links_each_acronym_at_first_use(stem):
    bad = unlinked(NOTEBOOK_DIR / f"{stem}.ipynb")
    assert not bad, f"{stem}: first use not linked to notebooks/GLOSSARY.md: {bad}"


def test_the_link_check_can_fail():
    known = {"PF": "pf", "KF": "kf"}
    cells = ["A $\\mathrm{PF}$ and `PF` are not uses. The [PF](GLOSSARY.md#pf) is; so are KFs.",
             "Later [KF](GLOSSARY.md#kf)."]
    uses = first_uses(cells, known)
    assert uses["PF"][0] == 0 and linked_at(cells[0], uses["PF"][1], "pf")
    assert uses["KF"][2] == "KFs" and not linked_at(cells[0], uses["KF"][1], "kf")
    assert canonical("CEP95", {"CEP"}) == "CEP" and canonical("LIAS", {"CEP"}) is None


# --------------------------------------------------------------------------- fronts and exercises

@pytest.mark.parametrize("stem", TAUGHT)
def test_taught_notebook_opens_with_a_teaching_front(stem):
    cells = nbformat.read(NOTEBOOK_DIR / f"{stem}.ipynb", as_version=4).cells
    front = cells[0].source
    words = len(re.sub(r"\]\([^)]*\)", "]", front).split())
    assert words <= 170, f"{stem}: teaching front has {words} words (about 150 at most)"
    for needed in ("You will learn", "Prerequisites", "Run time", "FAST", "full"):
        assert needed in front, f"{stem}: teaching front lacks {needed!r}"
    objectives = re.findall(r"^\s*\d+\.\s", front, flags=re.M)
    assert 3 <= len(objectives) <= 5, f"{stem}: {len(objectives)} learning objectives (want 3-5)"
    assert any(c.cell_type == "markdown" and c.source.lstrip().startswith("## Reproduction notes") for c in cells), \
        f"{stem}: no 'Reproduction notes' section"


@pytest.mark.parametrize("stem", TAUGHT)
def test_taught_notebook_has_checked_exercises(stem):
    cells = nbformat.read(NOTEBOOK_DIR / f"{stem}.ipynb", as_version=4).cells
    exercises = [i for i, c in enumerate(cells) if c.cell_type == "markdown" and "**Exercise" in c.source]
    assert len(exercises) >= 2, f"{stem}: {len(exercises)} exercises (want at least 2)"
    for k, i in enumerate(exercises, 1):
        assert re.search(r"[Pp]redict", cells[i].source), f"{stem}: exercise in cell {i} asks no prediction"
        pred, nxt = cells[i + 1], cells[i + 2]
        assert pred.cell_type == "code" and "prediction" in pred.metadata.get("tags", []), \
            f"{stem}: exercise in cell {i} is not followed by a cell tagged 'prediction'"
        line = re.fullmatch(rf'PREDICTION_{k} = None  # write "([^"]+)" or "([^"]+)"(: .+)?', pred.source.strip())
        assert line, f"{stem}: cell {i + 1} must be 'PREDICTION_{k} = None  # write \"<a choice>\" or \"<the other>\": " \
                     f"<what>', got {pred.source!r}"
        assert pred.metadata.get("claim") in line.groups()[:2], \
            f"{stem}: cell {i + 1}'s metadata 'claim' (what the answer key writes) is not one of its two choices"
        assert nxt.cell_type == "code" and re.search(r"^assert \w+\.holds", nxt.source, flags=re.M), \
            f"{stem}: exercise in cell {i} is not followed by a check cell asserting it"
        assert nxt.source.strip().endswith(f".against(PREDICTION_{k}, reveal=not CLASS)"), \
            f"{stem}: check cell {i + 2} does not read PREDICTION_{k}"
        assert len(nxt.source.strip().splitlines()) <= 4, f"{stem}: check cell {i + 2} is more than a line or two"


@pytest.mark.parametrize("stem", TAUGHT)
def test_taught_notebook_panels_say_what_to_see(stem):
    cells = nbformat.read(NOTEBOOK_DIR / f"{stem}.ipynb", as_version=4).cells
    for i, c in enumerate(cells):
        if c.cell_type == "code" and "uw.widgets.Panel(" in c.source:
            after = cells[i + 1] if i + 1 < len(cells) else None
            assert after is not None and "what_you_should_see" in after.source, \
                f"{stem}: panel in cell {i} has no 'what you should see' note after it"


# --------------------------------------------------------------------------- helpers of uwbwb.widgets

def test_what_you_should_see_limits():
    from uwbwb.widgets import SEE_MAX_CHARS, what_you_should_see

    assert what_you_should_see("one\ntwo").data == "**What you should see.** one two"
    for bad in ("", "a\nb\nc\nd", "x" * (SEE_MAX_CHARS + 1)):
        with pytest.raises(ValueError, match="text"):
            what_you_should_see(bad)


def assert_reads_predictions(check):
    """``check`` read against its right answer, its wrong one, none (numbers hidden, unless revealed) and a
    prediction that is not a choice. Called on a check from every exercise function of the package."""
    right, wrong = check.outcome, next(c for c in check.choices if c != check.outcome)
    assert check.outcome == check.choices[0 if check.holds else 1]
    yes, no = check.against(right), check.against(wrong)
    assert yes.right is True and "✔ Right" in yes._repr_markdown_() and "Numbers:" in yes._repr_markdown_()
    assert no.right is False and "Not what the run shows" in no._repr_markdown_()
    assert f"the run shows **{right}**" in no._repr_markdown_() and "Numbers:" in no._repr_markdown_()
    hidden = check.against(None)._repr_markdown_()
    assert repr(check.against(None)) == hidden                      # the notebook's text/plain output: no number
    assert "Write your prediction first" in hidden and "Numbers:" not in hidden and right in hidden and wrong in hidden
    assert not any(name in hidden for name in check.numbers)
    assert check.against(None).right is None and "Numbers:" in check.against(None, reveal=True)._repr_markdown_()
    with pytest.raises(ValueError, match="PREDICTION"):
        check.against("perhaps")


def test_every_exercise_function_is_read_against_predictions_in_a_test():
    # each function of the package that returns an ExerciseCheck is called in a test module that feeds its checks
    # a right, a wrong and no prediction (assert_reads_predictions)
    defined = [(path.parent.name, node.name) for path in sorted((ROOT / "uwbwb").rglob("exercises.py"))
               for node in ast.parse(path.read_text()).body
               if isinstance(node, ast.FunctionDef) and ast.unparse(node.returns or ast.Constant(None)) == "ExerciseCheck"]
    assert len(defined) >= 14, defined                                   # two per taught notebook
    tests = [p.read_text() for p in (ROOT / "tests").rglob("test_*.py")]
    untested = [f"{unit}.{f}" for unit, f in defined
                if not any("assert_reads_predictions(" in t and re.search(rf"\.{f}\(", t) for t in tests)]
    assert not untested, f"exercise checks never read against a right and a wrong prediction: {untested}"


def test_exercise_check_shows_its_verdict_and_reads_a_prediction():
    from uwbwb.widgets import ExerciseCheck

    ok = ExerciseCheck("A above B", True, {"A (cm)": 2.0, "B (cm)": 1.0}, ("above", "not above"), "Because.")
    assert str(ok).startswith("holds: A above B") and "✔" in ok._repr_markdown_()
    no = ExerciseCheck("A above B", False, {"A (cm)": 1.0, "B (cm)": 2.0}, ("above", "not above"))
    assert "DOES NOT HOLD" in str(no) and "✘" in no._repr_markdown_()
    assert (ok.outcome, no.outcome) == ("above", "not above")
    assert ok.against("not above").right is False and no.against("not above").right is True
    assert "Because." in ok.against("above")._repr_markdown_() and "Because." not in ok.against(None)._repr_markdown_()
    for check in (ok, no):
        assert_reads_predictions(check)
    with pytest.raises(TypeError):
        no.numbers["A (cm)"] = 3.0                                   # frozen numbers
    for bad in (("above",), ("x", "x")):
        with pytest.raises(ValueError, match="choices"):
            ExerciseCheck("A above B", True, {}, bad)


def test_the_claim_is_not_always_the_first_choice():
    """A student who finds the claim first in one prediction line cannot read the others' answers off their order:
    across the taught notebooks the claim comes second in at least a third of them."""
    places = [re.search(r'write "([^"]+)"', c.source).group(1) == c.metadata["claim"]
              for stem in TAUGHT for c in nbformat.read(NOTEBOOK_DIR / f"{stem}.ipynb", as_version=4).cells
              if "prediction" in c.metadata.get("tags", [])]
    assert len(places) >= 14 and 3 * places.count(False) >= len(places), places


def test_the_guide_to_tables_a_class_sees_is_shown_in_class_mode():
    """Notebook 04's "How to read them" explains the verdict tables its class-mode run shows (that cell is not tagged
    ``research``), so the guide is not folded away either: none of its cells is ``research``, each keeps to the class
    limit on words, and together they hold the whole guide (its last item, the ranging term, included)."""
    from uwbwb import classroom

    cells = nbformat.read(NOTEBOOK_DIR / "04_doppler_beacons.ipynb", as_version=4).cells
    start = next(k for k, c in enumerate(cells) if c.source.startswith("How to read them"))
    table = next(k for k, c in enumerate(cells) if "display(facts.verdict_table(f))" in c.source)
    assert start < table and classroom.RESEARCH_TAG not in cells[table].metadata.get("tags", [])
    guide = [c for c in cells[start:table] if c.cell_type == "markdown"]
    for c in guide:
        assert classroom.RESEARCH_TAG not in c.metadata.get("tags", []), c.source[:60]
        assert classroom._prose_words(c.source) <= classroom.MAX_MARKDOWN_WORDS, c.source[:60]
    assert "**The ranging term.**" in "".join(c.source for c in guide)
