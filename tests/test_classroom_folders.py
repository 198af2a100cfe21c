"""``make class``'s two folders (:mod:`uwbwb.classroom`): student copies without answers whose links work, and
answers with handouts that show everything offline."""

from __future__ import annotations

import base64
import copy
import html as html_mod
import io
import re
import subprocess
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import nbformat  # noqa: E402
import pytest  # noqa: E402

from tests.browser_support import CHROMIUM, launch_chromium  # noqa: E402
from uwbwb import classroom, reproduce  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
NOTEBOOKS = REPO / "notebooks"
WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"
WIDGET_STATE = "application/vnd.jupyter.widget-state+json"


def _md(text, *tags):
    cell = nbformat.v4.new_markdown_cell(text)
    cell.metadata["tags"] = list(tags)
    return cell


def _code(source, *tags, outputs=(), count=None):
    cell = nbformat.v4.new_code_cell(source)
    cell.metadata["tags"] = list(tags)
    cell.outputs = [nbformat.from_dict(o) for o in outputs]
    cell.execution_count = count
    return cell


def _notebook(*cells):
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells = list(cells)
    return nb


def _plain(html: str) -> str:
    """The text of an HTML page (tags dropped, entities decoded)."""
    return html_mod.unescape(re.sub(r"<[^>]*>", "", html))


def _relative_hrefs(html: str) -> list[str]:
    return [h for h in re.findall(r"<a\b[^>]*\bhref=\"([^\"]+)\"", html)
            if not h.startswith("#") and not re.match(r"^[a-z]+:", h)]


def _png() -> str:
    fig = plt.figure(figsize=(1, 1))
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


# ------------------------------------------------------------------ student copies

def test_set_parameters_rewrites_the_values_and_keeps_the_comments():
    source = "FAST = False         # CI sizes\nCLASS = False  # a lecture\nSEED = 0\nSIZES = (1,\n         2)\n"
    assert classroom.set_parameters(source, {"FAST": True, "CLASS": True}) == (
        "FAST = True          # CI sizes\nCLASS = True   # a lecture\nSEED = 0\nSIZES = (1,\n         2)\n")
    with pytest.raises(ValueError, match="assigns no CLASS"):
        classroom.set_parameters("FAST = False\n", {"CLASS": True})
    with pytest.raises(ValueError, match="several lines"):
        classroom.set_parameters(source, {"SIZES": 1})


def test_a_student_copy_holds_no_output_and_says_class_in_its_parameters_cell():
    png = {"output_type": "display_data", "data": {"image/png": "iVBOR", "text/plain": "<Figure>"}, "metadata": {}}
    nb = _notebook(_md("# Lab"), _code("FAST = False\nCLASS = False", "parameters", count=1),
                   _code("FAST = True\nCLASS = True", "injected-parameters", count=2),
                   _code("x = 1", outputs=[png], count=3),
                   _code("print('bookkeeping')", "research", count=4,
                         outputs=[{"output_type": "stream", "name": "stdout", "text": "answer 42\n"}]))
    nb.metadata["widgets"] = {WIDGET_STATE: {"state": {}}}
    student = classroom.student_notebook(nb, {"FAST": True, "CLASS": True})
    code = [c for c in student.cells if c.cell_type == "code"]
    assert [c.outputs for c in code] == [[], [], []] and {c.execution_count for c in code} == {None}
    assert [c.source for c in code][0] == "FAST = True\nCLASS = True"          # in the cell a student reads
    assert not any("injected-parameters" in c.metadata["tags"] for c in code)
    assert code[2].metadata["jupyter"] == {"source_hidden": True, "outputs_hidden": True}
    assert "widgets" not in student.metadata
    assert nb.cells[3].outputs and nb.cells[1].source.startswith("FAST = False")    # the original is untouched
    assert classroom.class_values(["FAST", "SEED"]) == {"FAST": True}


def test_the_student_folder_of_the_notebooks(tmp_path):
    """Every notebook unexecuted, FAST and CLASS True in its parameters cell, research folded, the glossary beside
    them and every relative link resolving (no kernel: this is the copy, not the run)."""
    student = tmp_path / "student"
    _, copies = classroom.write_student_folder(reproduce.select_notebooks(NOTEBOOKS), student)
    assert sorted(p.name for p in copies.values()) == sorted(p.name for p in NOTEBOOKS.glob("*.ipynb"))
    links = 0
    for copy in copies.values():
        nb = nbformat.read(copy, as_version=4)
        assert not any(c.get("outputs") for c in nb.cells), copy.name
        values = reproduce.notebook_parameters(copy)
        assert values["CLASS"] is True and values["FAST"] is True, copy.name
        research = [c for c in nb.cells if "research" in c.metadata.get("tags", [])]
        assert research and all(c.metadata["jupyter"]["source_hidden"] for c in research), copy.name
        links += len(classroom.notebook_links(nb))
    assert (student / "GLOSSARY.md").read_text() == (NOTEBOOKS / "GLOSSARY.md").read_text()
    assert links > 0 and classroom.unresolved_links(student) == []
    sheets = (student / classroom.LAB_SHEETS_NAME).read_text()           # the routes, without the answers
    teaching = (NOTEBOOKS.parent / "TEACHING.md").read_text()
    answers = teaching[teaching.index("\n## Answers"):]
    assert "### Route A" in sheets and "### Route B" in sheets and sheets.count("**The questions.**") == 2
    assert "## Answers" not in sheets and not any(ln in sheets for ln in answers.splitlines() if len(ln) > 40)
    with pytest.raises(ValueError, match="Two two-hour routes"):
        classroom.lab_sheets("# Teaching\n\n## Answers: notebook 00\n")


def test_linked_files_are_copied_beside_the_notebooks_and_links_follow_them(tmp_path):
    root = tmp_path / "project"
    (root / "notebooks" / "img").mkdir(parents=True)
    (root / "docs").mkdir()
    (root / "notebooks" / "img" / "f.png").write_bytes(b"png")
    (root / "notebooks" / "GLOSSARY.md").write_text("[kf](#kf), see [B](../docs/B.md)\n")
    (root / "docs" / "A.md").write_text("[glossary](../notebooks/GLOSSARY.md) and [C](C.md#top)\n")
    (root / "docs" / "B.md").write_text("B\n")
    (root / "docs" / "C.md").write_text("C\n")
    (root / "README.md").write_text("not linked\n")
    nb = _notebook(_md("[g](GLOSSARY.md#x), [anatomy](../docs/A.md#s), ![fig](img/f.png), "
                       "`[code](nowhere.md)`, [web](https://example.org/a.md), <a href=\"../docs/B.md\">B</a>"),
                   _code("FAST = False", "parameters"))
    nbformat.write(nb, root / "notebooks" / "00_a.ipynb")
    out = tmp_path / "student"
    classroom.write_student_folder([root / "notebooks" / "00_a.ipynb"], out)
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == [
        "00_a.ipynb", "GLOSSARY.md", "docs/A.md", "docs/B.md", "docs/C.md", "img/f.png"]
    text = nbformat.read(out / "00_a.ipynb", as_version=4).cells[0].source
    assert "](docs/A.md#s)" in text and "](GLOSSARY.md#x)" in text and 'href="docs/B.md"' in text
    assert "`[code](nowhere.md)`" in text and "](https://example.org/a.md)" in text     # code and URLs as they were
    assert "](../GLOSSARY.md)" in (out / "docs" / "A.md").read_text()
    assert classroom.unresolved_links(out) == []
    (out / "docs" / "C.md").unlink()
    assert classroom.unresolved_links(out) == ["docs/A.md: C.md#top"]


# ------------------------------------------------------------------ handouts

def test_mathtext_source_translates_what_mathtext_lacks():
    assert classroom.mathtext_source(r"\mathcal N(\mu, \sigma)") == r"\mathcal{N}(\mu, \sigma)"
    assert classroom.mathtext_source(r"\tfrac12 + \frac1K") == r"\frac{1}{2} + \frac{1}{K}"
    assert classroom.mathtext_source(r"a \le b, \left( c \right)") == r"a \leq  b, \left( c \right)"
    for tex in (r"\sum_i \big(\lVert p - a_i \rVert - r_i\big)^2", r"\lvert V\rvert", r"\mathbf P_0",
                r"A = \begin{bmatrix}I & TI\\0 & I\end{bmatrix}", r"x \ge 0 \ne y", r"\hat{\mathbf P}_0"):
        assert "<path" in classroom.math_svg(tex), tex


def test_math_svg_is_an_inline_vector_on_the_baseline():
    svg = classroom.math_svg("x_i^2")
    assert svg.startswith("<svg") and "<path" in svg and 'aria-label="x_i^2"' in svg and "<script" not in svg
    assert float(re.search(r"vertical-align: (-?[\d.]+)em", svg).group(1)) < 0      # the subscript hangs below
    assert classroom.math_svg("x", display=True).startswith('<div class="uwbwb-math-display"><svg')
    with pytest.raises(ValueError, match="mathtext cannot draw"):
        classroom.math_svg(r"\begin{bmatrix}a\\b\\c\end{bmatrix}")


def _panel_notebook():
    """An executed notebook with a formula, a glossary link, a class parameters cell and a saved panel."""
    png = _png()
    state = {
        "box": {"model_name": "VBoxModel", "state": {"_dom_classes": ["uwbwb-panel"],
                                                     "children": ["IPY_MODEL_title", "IPY_MODEL_controls",
                                                                  "IPY_MODEL_readout", "IPY_MODEL_figure"]}},
        "bar": {"model_name": "HBoxModel", "state": {"children": ["IPY_MODEL_bar_text", "IPY_MODEL_bar_done"]}},
        "bar_text": {"model_name": "HTMLModel", "state": {"value": "sweep: 100%"}},
        "bar_done": {"model_name": "FloatProgressModel", "state": {"value": 3.0, "max": 3.0}},
        "title": {"model_name": "HTMLModel", "state": {"value": "<b>Explorer of a panel</b>"}},
        "controls": {"model_name": "VBoxModel", "state": {"children": ["IPY_MODEL_tag", "IPY_MODEL_window"]}},
        "tag": {"model_name": "DropdownModel", "state": {"description": "tag", "_options_labels": ["t0", "t1"],
                                                         "index": 1}},
        "window": {"model_name": "FloatSliderModel", "state": {"description": "window (s)", "value": 20.0,
                                                               "readout_format": ".0f"}},
        "readout": {"model_name": "HTMLModel", "state": {"value": "<table><tr><th>CEP50 (m)</th><td>0.1194</td>"
                                                                  "</tr></table>"}},
        "figure": {"model_name": "OutputModel", "state": {"outputs": [
            {"output_type": "display_data", "data": {"image/png": png, "text/plain": "<Figure>"}, "metadata": {}}]}},
    }
    view = {"output_type": "execute_result", "execution_count": 3, "metadata": {},
            "data": {WIDGET_VIEW: {"model_id": "box", "version_major": 2, "version_minor": 0},
                     "text/plain": "Explorer of a panel"}}
    bar = {"output_type": "display_data", "metadata": {},
           "data": {WIDGET_VIEW: {"model_id": "bar", "version_major": 2, "version_minor": 0}, "text/plain": "0%"}}
    nb = _notebook(_md("An [EKF](GLOSSARY.md#ekf) fixes $x_i^2$:\n\n$$\\sum_i \\lVert p - a_i \\rVert$$"),
                   _code("FAST = True\nCLASS = True", "parameters", count=1),
                   _code("sweep()", outputs=[bar], count=2), _code("panel", outputs=[view], count=3))
    nb.metadata["widgets"] = {WIDGET_STATE: {"state": state, "version_major": 2, "version_minor": 0}}
    return nb, png


def test_a_handout_shows_formulas_panels_and_class_values_offline():
    nb, png = _panel_notebook()
    tex_left = []
    html = classroom.handout_html(nb, name="00_lab", link_map={"GLOSSARY.md": "GLOSSARY.html"}, tex_left=tex_left)
    assert classroom.handout_problems(html, nb, {"FAST": True, "CLASS": True}) == [] and tex_left == []
    assert classroom.markdown_formulas(nb) == 2 and "$x_i^2$" not in html             # both formulas drawn
    assert classroom.notebook_panels(nb) == 1                                         # a bar is no panel
    assert 'href="GLOSSARY.html#ekf"' in html
    text = " ".join(_plain(html).split())
    assert "CLASS = True" in text and "Explorer of a panel" in text and "tag: t1" in text
    assert "window (s): 20" in text and "CEP50 (m)0.1194" in text and classroom.STATIC_PANEL_NOTE in text
    assert f'src="data:image/png;base64,{png}"' in html                            # the panel's figure
    assert '<progress max="3.0" value="3.0">' in html or '<progress value="3.0" max="3.0">' in html
    assert text.count(classroom.STATIC_PANEL_NOTE) == 1 and "sweep: 100%" in text      # a bar is no panel
    assert WIDGET_STATE in nb.metadata["widgets"]                                   # the notebook is untouched
    assert "<title>00_lab</title>" in html


def test_a_handout_that_does_not_show_everything_offline_is_named():
    """What a class run checks of each handout (:func:`uwbwb.classroom.handout_problems`), on hand-spoilt pages."""
    nb, _ = _panel_notebook()
    values = {"FAST": True, "CLASS": True}
    good = classroom.handout_html(nb, name="00_lab")
    assert classroom.handout_problems(good, nb, values) == []
    cdn = '<script src="https://cdn.jsdelivr.net/npm/mathjax@3/es5/tex-chtml.js"></script>'
    first_formula = good.index("<svg", good.index("jp-MarkdownCell"))
    spoilt = {
        "a CDN": (good.replace("</head>", cdn + '<link rel="stylesheet" href="https://example.org/a.css"></head>'),
                  ["script loaded from https://cdn.jsdelivr.net/npm/mathjax@3/es5/tex-chtml.js",
                   "stylesheet from https://example.org/a.css", "mentions MathJax"]),
        "a raw formula": (good[:first_formula] + "$x_i^2$" + good[good.index("</svg>", first_formula) + 6:],
                          ["TeX left in the Markdown text: $x_i^2$",
                           "1 formulas drawn for the 2 of the notebook's Markdown"]),
        "no panel figure": (re.sub(r'<img\b[^>]*src="data:image/png;base64,[^"]*"[^>]*>', "", good),
                            ["0 static panels with their figure for the notebook's 1 panels"]),
    }
    for what, (page, expected) in spoilt.items():
        assert classroom.handout_problems(page, nb, values) == expected, what
    tex_out = copy.deepcopy(nb)
    tex_out.cells.append(_code("error", count=4, outputs=[
        {"output_type": "stream", "name": "stdout", "text": "an error of $\\frac{1}{K}$\n"},
        {"output_type": "stream", "name": "stdout", "text": "a lab PC costs $5 and $6 a day; C:\\Users\\lab\n"}]))
    tex_out.cells[1].source = "FAST = True\nCLASS = False"
    assert classroom.handout_problems(classroom.handout_html(tex_out), tex_out, values) == [    # prices, paths: no TeX
        "TeX left in the output text: $\\frac{1}{K}$", "CLASS = True not shown"]


def test_a_formula_mathtext_cannot_draw_is_shown_as_tex_and_reported():
    tex_left = []
    html = classroom.handout_html(_notebook(_md(r"$$\begin{bmatrix}a\\b\\c\end{bmatrix}$$")), tex_left=tex_left)
    assert tex_left == [r"\begin{bmatrix}a\\b\\c\end{bmatrix}"] and 'class="uwbwb-tex"' in html


def test_every_formula_of_the_notebooks_and_the_glossary_is_drawn():
    left = {}
    for path in sorted(NOTEBOOKS.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        nb.cells = [c for c in nb.cells if c.cell_type == "markdown"]   # the formulas: no code cell to render
        tex_left = []
        classroom.handout_html(nb, tex_left=tex_left)
        left[path.name] = tex_left
    tex_left = []
    classroom.markdown_page_html((NOTEBOOKS / "GLOSSARY.md").read_text(encoding="utf-8"), name="Glossary",
                                 tex_left=tex_left)
    left["GLOSSARY.md"] = tex_left
    assert {k: v for k, v in left.items() if v} == {}, "extend classroom.mathtext_source or rewrite the formula"


def test_lab_opens_the_student_folder_on_request():
    def lab(*args):
        return subprocess.run(["make", "-n", "lab", *args], cwd=REPO, capture_output=True, text=True,
                              check=True).stdout

    assert "--notebook-dir=class/student " in lab("LAB_DIR=class/student")
    assert "--notebook-dir=notebooks " in lab()


# ------------------------------------------------------------------ a handout opened offline in a browser

#: What a page shows, read in the browser: its images, the math SVGs of its Markdown cells (and those without a
#: drawn outline or size), the visible text of its rendered Markdown, each static panel's loaded images, its text.
_JS_HANDOUT = """() => {
  const math = [...document.querySelectorAll('.jp-MarkdownCell svg.uwbwb-math')];
  const loaded = img => img.complete && img.naturalWidth > 0;
  return {
    images: [...document.images].map(img => [img.src.slice(0, 60), img.naturalWidth]),
    formulas: math.length,
    undrawn: math.filter(svg => {const r = svg.getBoundingClientRect();
                                 return !(r.width > 0 && r.height > 0 && svg.querySelector('path[d]'));}).length,
    markdown: [...document.querySelectorAll('.jp-RenderedMarkdown')].map(e => e.innerText).join('\\n'),
    panels: [...document.querySelectorAll('.uwbwb-static-panel')].map(p => [...p.querySelectorAll('img')]
                                                                               .filter(loaded).length),
    text: document.body.innerText,
  };
}"""


def _browser_problems(browser, page_path: Path, *, formulas: int, panels: int, values: dict) -> list[str]:
    """Open ``page_path`` in a fresh page of ``browser`` with every request other than the file itself aborted, and
    say what an offline reader would miss: a request that left the file (data: URIs stay in it), an image that did
    not load, a formula not drawn as an SVG of the page (``formulas`` in the notebook's Markdown) or left as TeX in
    the text, a panel (``panels`` in the notebook) without its static figure, a class parameter value not shown."""
    own = page_path.resolve().as_uri()
    left: list[str] = []

    def only_the_file(route):
        if route.request.url == own or route.request.url.startswith("data:"):
            route.continue_()
        else:
            left.append(route.request.url)
            route.abort()

    context = browser.new_context()
    try:
        page = context.new_page()
        page.on("websocket", lambda ws: left.append(ws.url))
        page.route("**/*", only_the_file)
        page.goto(own, wait_until="load")
        seen = page.evaluate(_JS_HANDOUT)
    finally:
        context.close()
    problems = [f"request left the file: {url}" for url in sorted(left)]
    problems += [f"image not shown: {src}" for src, width in seen["images"] if width == 0]
    if seen["formulas"] != formulas or seen["undrawn"]:
        problems.append(f"{seen['formulas'] - seen['undrawn']} of the notebook's {formulas} formulas drawn")
    problems += [f"TeX left in the text: {tex}" for tex in classroom.TEX_LEFT.findall(seen["markdown"])]
    if len(seen["panels"]) != panels or not all(seen["panels"]):
        problems.append(f"{sum(n > 0 for n in seen['panels'])} of the notebook's {panels} panels shown with their "
                        "figure")
    problems += [f"{name} = {value!r} not shown" for name, value in values.items()
                 if not re.search(rf"\b{name}\s*=\s*{value!r}(?!\w)", seen["text"])]
    return problems


@pytest.fixture
def chromium():
    """The system Chromium, headless (as the browser test's), or a skip saying what is missing; started after the
    test's other fixtures (a notebook runs before Playwright's event loop is up) and closed after it."""
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} not installed (apt-get install chromium): the handout is opened in the system "
                    "Chromium only")
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed in this environment")
    with sync_api.sync_playwright() as pw:
        browser = launch_chromium(pw)
        yield browser
        browser.close()


@pytest.mark.browser
def test_the_offline_handout_check_catches_a_cdn_script_a_raw_formula_and_a_missing_figure(chromium, tmp_path):
    page = tmp_path / "bad.html"
    page.write_text(
        '<html><head><script src="https://cdn.jsdelivr.net/npm/mathjax@3/es5/tex-chtml.js"></script></head><body>'
        '<div class="jp-MarkdownCell"><div class="jp-RenderedMarkdown"><p>An error of $\\frac{1}{K}$ and '
        + classroom.math_svg("x_i") + '</p></div></div>'
        '<div class="uwbwb-static-panel"><img src="https://example.org/panel.png" alt="panel figure"></div>'
        '<pre>FAST = True\nCLASS = False</pre></body></html>', encoding="utf-8")
    assert _browser_problems(chromium, page, formulas=2, panels=1, values={"FAST": True, "CLASS": True}) == [
        "request left the file: https://cdn.jsdelivr.net/npm/mathjax@3/es5/tex-chtml.js",
        "request left the file: https://example.org/panel.png",
        "image not shown: https://example.org/panel.png",
        "1 of the notebook's 2 formulas drawn",
        "TeX left in the text: $\\frac{1}{K}$",
        "0 of the notebook's 1 panels shown with their figure",
        "CLASS = True not shown"]


# ------------------------------------------------------------------ the class run of a notebook

@pytest.fixture(scope="module")
def class_00(tmp_path_factory):
    """``make class`` of notebook 00 (one execution, read by the tests below)."""
    out = tmp_path_factory.mktemp("class-00") / "class"
    assert classroom.main(["--only", "00", "--notebooks-dir", str(NOTEBOOKS), "--out", str(out)]) == 0
    return out


@pytest.mark.notebook
@pytest.mark.browser
def test_the_handout_of_notebook_00_shows_everything_offline_in_chromium(class_00, chromium):
    """The handout opened in headless Chromium with every request but the file's own aborted: nothing requested,
    every image loaded, every formula of the notebook's Markdown an SVG of the page and none left as TeX, each
    panel a static figure, the class values shown."""
    nb = nbformat.read(class_00 / "answers" / "00_quickstart.ipynb", as_version=4)
    values = classroom.class_values(reproduce.notebook_parameters(class_00 / "student" / "00_quickstart.ipynb"))
    formulas, panels = classroom.markdown_formulas(nb), classroom.notebook_panels(nb)
    assert formulas > 0 and panels > 0 and values == {"FAST": True, "CLASS": True}
    assert _browser_problems(chromium, class_00 / "answers" / "00_quickstart.html", formulas=formulas,
                             panels=panels, values=values) == []


@pytest.mark.notebook
def test_class_folders_of_notebook_00(class_00):
    out = class_00
    student, answers = out / "student", out / "answers"
    given = nbformat.read(student / "00_quickstart.ipynb", as_version=4)
    assert not any(c.get("outputs") for c in given.cells)
    assert reproduce.notebook_parameters(student / "00_quickstart.ipynb")["CLASS"] is True
    assert (student / "GLOSSARY.md").is_file() and classroom.unresolved_links(student) == []
    assert not (student / "TEACHING.md").exists()                       # the answers stay with the lecturer
    assert "## Answers" not in (student / classroom.LAB_SHEETS_NAME).read_text()   # the routes go to the students
    executed = nbformat.read(answers / "00_quickstart.ipynb", as_version=4)
    params = [c for c in executed.cells if "parameters" in c.metadata.get("tags", [])]
    assert [c.source for c in params] == [c.source for c in given.cells if "parameters" in c.metadata.get("tags", [])]
    assert not any("injected-parameters" in c.metadata.get("tags", []) for c in executed.cells)
    assert classroom.image_count(executed) > 0
    assert {p.name for p in answers.iterdir()} == {"00_quickstart.ipynb", "00_quickstart.html", "TEACHING.md",
                                                   "GLOSSARY.md", "GLOSSARY.html", "docs"}
    assert (student / "docs" / "run_times.md").is_file()                  # the front's run-time table, linked
    assert classroom.unresolved_links(answers) == []                      # TEACHING.md's glossary link too
    html = (answers / "00_quickstart.html").read_text(encoding="utf-8")
    values = classroom.class_values(reproduce.notebook_parameters(student / "00_quickstart.ipynb"))
    assert classroom.markdown_formulas(executed) > 0 and classroom.notebook_panels(executed) > 0
    assert values == {"FAST": True, "CLASS": True} and classroom.handout_problems(html, executed, values) == []
    assert "CLASS = False" not in " ".join(_plain(html).split())
    hrefs = _relative_hrefs(html)
    assert hrefs and all((answers / h.partition("#")[0]).is_file() for h in hrefs), hrefs
    glossary = _notebook(_md((answers / "GLOSSARY.md").read_text(encoding="utf-8")))
    assert classroom.handout_problems((answers / "GLOSSARY.html").read_text(encoding="utf-8"), glossary, {}) == []
