"""README's package layout and docs/ANATOMY.md list every module of the package."""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "uwbwb"


def _layout() -> dict[str, str]:
    """README's package-layout block as ``{entry: text}``, an entry per line starting ``uwbwb/``."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Package layout", 1)[1].split("```", 2)[1]
    entries: dict[str, str] = {}
    key = None
    for line in section.splitlines():
        m = re.match(r"uwbwb/(\S+)", line)
        if m:
            key = m.group(1)
            entries[key] = line[m.end():]
        elif key is not None:
            entries[key] += " " + line
    return entries


def _modules():
    """``(package or None, module stem)`` of every module; experiment packages as ``("experiments", name)``."""
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if "__pycache__" in rel.parts:
            continue
        if len(rel.parts) == 1:
            yield None, rel.stem
        elif rel.parts[0] == "experiments":
            if len(rel.parts) > 2:
                yield "experiments", rel.parts[1]
        elif rel.stem != "__init__":
            yield "/".join(rel.parts[:-1]), rel.stem        # a sub-package's module: ("filters/ekf", "core")


def _word(word: str, text: str) -> bool:
    return re.search(rf"(?<![\w]){re.escape(word)}(?![\w])", text, re.IGNORECASE) is not None


def test_readme_package_layout_lists_every_module():
    entries = _layout()
    missing = []
    for package, stem in sorted(set(_modules()), key=str):
        if package is None:
            if stem == "__main__":
                ok = any("__main__" in t for t in entries.values())
            else:
                ok = f"{stem}.py" in entries
        else:
            top = package.split("/")[0]             # a sub-package's modules are listed in its package's entry
            ok = f"{top}/" in entries and _word(stem, entries[f"{top}/"])
        if not ok:
            missing.append(f"{package}/{stem}" if package else f"{stem}.py")
    assert not missing, f"README's package layout does not list: {missing}"


def test_anatomy_lists_every_module():
    text = (ROOT / "docs" / "ANATOMY.md").read_text(encoding="utf-8")
    missing = []
    for package, stem in sorted(set(_modules()), key=str):
        name = (f"`{stem}.py`" if package is None else
                f"`experiments/{stem}/`" if package == "experiments" else f"`{package}/{stem}.py`")
        if name not in text:
            missing.append(name)
    assert not missing, f"docs/ANATOMY.md does not list: {missing}"


def test_the_checks_see_a_missing_module(tmp_path, monkeypatch):
    # both checks would pass vacuously if they found no modules
    fake = tmp_path / "uwbwb"
    (fake / "filters").mkdir(parents=True)
    (fake / "filters" / "brand_new.py").write_text("")
    (fake / "filters" / "deep").mkdir()
    (fake / "filters" / "deep" / "nested_new.py").write_text("")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", fake)
    assert {("filters", "brand_new"), ("filters/deep", "nested_new")} <= set(_modules())
    entries = _layout()
    assert not _word("brand_new", entries["filters/"])
    assert not _word("nested_new", entries["filters/"])
