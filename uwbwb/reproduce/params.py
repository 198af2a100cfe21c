"""Notebook parameters for ``reproduce``: what a notebook declares, and checking and typing given values.

A notebook declares its parameters in its one code cell tagged ``parameters``; each value given on the
command line (``-p NAME VALUE``) or from Python is checked against the notebook's specification
(:mod:`uwbwb.notebook_params`) and reaches the notebook, through an injected cell written here as
Python literals, with the type the specification gives it.
"""

from __future__ import annotations

import ast
import json
import os
from pathlib import Path
from typing import Any, Iterable, Mapping

from .. import notebook_params

__all__ = ["INJECTED_TAG", "RESERVED_PARAMETERS", "SCHEDULER_PARAMETER", "injected_source", "notebook_parameters",
           "parameterized", "resolve_parameters"]


#: Parameters set by the runner itself; they cannot be overridden.
RESERVED_PARAMETERS = ("SUMMARY_PATH",)

#: The notebook parameter that receives the Dask scheduler (``reproduce --scheduler``).
SCHEDULER_PARAMETER = "DASK_SCHEDULER"

_MISSING = object()


def notebook_parameters(notebook: str | os.PathLike) -> dict[str, Any]:
    """The parameters a notebook declares and their defaults.

    Read from its one code cell tagged ``parameters``: every top-level
    ``NAME = <literal>`` assignment. A default that is not a literal (an
    expression) is returned as None, i.e. it takes any literal.

    The notebook is read as plain JSON (nbformat's import costs seconds, and every
    problem with the parameters must be reported before any of that).

    Raises
    ------
    ValueError
        The notebook is not notebook JSON, has no such cell, several, or a cell that is not valid Python.
    """
    path = Path(notebook)
    try:
        nb = json.loads(path.read_text(encoding="utf-8"))
        cells = [c for c in nb["cells"] if c.get("cell_type") == "code"
                 and "parameters" in (c.get("metadata") or {}).get("tags", [])]
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path.name}: not a Jupyter notebook ({type(exc).__name__}: {exc})") from None
    if len(cells) != 1:
        raise ValueError(f"{path.name}: expected exactly one code cell tagged 'parameters', found {len(cells)}")
    source = cells[0].get("source", "")
    source = "".join(source) if isinstance(source, list) else str(source)
    try:
        tree = ast.parse(source)
    except SyntaxError as exc:
        raise ValueError(f"{path.name}: parameters cell, line {exc.lineno}: {exc.msg}") from None
    declared = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            name, value = node.targets[0].id, node.value
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
            name, value = node.target.id, node.value
        else:
            continue
        try:
            declared[name] = ast.literal_eval(value)
        except (ValueError, SyntaxError, TypeError):
            declared[name] = None
    return declared


def resolve_parameters(notebooks: Iterable[str | os.PathLike], parameters: Mapping[str, Any] | None = None,
                       *, text: Mapping[str, str] | None = None, quick: bool = False) -> dict[Path, dict[str, Any]]:
    """The parameters each notebook will receive, checked against what it declares.

    Parameters
    ----------
    notebooks
        The selected notebooks.
    parameters
        Python values (e.g. ``{"FAST": True, "N_TRIALS": 5}``): each must satisfy the
        notebook's spec (:func:`uwbwb.notebook_params.specs_for`).
    text
        Values as typed on the command line (``-p NAME VALUE``): parsed by each
        notebook's spec (:meth:`uwbwb.notebook_params.Spec.parse`). A name in both wins from ``text``.
    quick
        Every notebook runs with ``FAST=True`` (``--quick``); an explicit ``FAST=False`` is refused.

    Returns
    -------
    dict
        Notebook path → ``{name: value}`` for the names that notebook declares, each
        value of the type its spec gives.

    Raises
    ------
    ValueError
        A reserved name, a name that no selected notebook declares (the message lists
        the valid names), a value that does not satisfy its spec, ``FAST=False`` with
        ``quick``, or (when the notebook will run with ``FAST=True``) an explicit value
        that its FAST mode replaces or lowers, or (with ``CLASS=True``) one that class mode sets itself (see
        :func:`uwbwb.notebook_params.conflict`).
    """
    notebooks = [Path(nb) for nb in notebooks]
    parameters, text = dict(parameters or {}), dict(text or {})
    given = parameters | text
    reserved = sorted(set(given) & set(RESERVED_PARAMETERS))
    if reserved:
        raise ValueError(f"parameter(s) {', '.join(reserved)} are set by the runner and cannot be passed")
    declared = {nb: notebook_parameters(nb) for nb in notebooks}
    valid = sorted({name for d in declared.values() for name in d} - set(RESERVED_PARAMETERS))
    unknown = [name for name in given if not any(name in d for d in declared.values())]
    if unknown:
        stems = ", ".join(nb.stem for nb in notebooks)
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}: not declared by {stems}; "
                         f"valid names: {', '.join(valid)}")
    resolved = {}
    for nb, defaults in declared.items():
        specs = notebook_params.specs_for(nb.stem, defaults)
        params = {}
        for name in given:
            if name not in defaults:
                continue
            try:
                params[name] = (specs[name].parse(text[name], name) if name in text
                                else specs[name].validate(parameters[name], name))
            except ValueError as exc:
                what = "" if name in text else "parameter "
                raise ValueError(f"{nb.stem}: {what}{exc} (the default of {name} is {defaults[name]!r})") from None
        if quick and "FAST" in defaults:
            if params.get("FAST", True) is not True:
                raise ValueError(f"--quick sets FAST=True, but FAST={params['FAST']!r} was given too: "
                                 f"drop --quick or the FAST value")
            params = {"FAST": True} | params
        for mode in ("FAST", "CLASS"):
            if params.get(mode, defaults.get(mode)) is True:
                for name, value in params.items():
                    problem = notebook_params.conflict(mode, nb.stem, name, value, specs[name])
                    if problem is not None:
                        raise ValueError(problem)
        resolved[nb] = params
    return resolved

#: Tag papermill gives the cell of injected parameters (kept, so that tools reading executed notebooks find it).
INJECTED_TAG = "injected-parameters"


def injected_source(parameters: Mapping[str, Any]) -> str:
    """The injected parameters cell: one ``NAME = <Python literal>`` line per parameter.

    Every value is written as its ``repr``, which must read back as the same value of
    the same type (papermill itself would turn a tuple into a string).

    Raises
    ------
    ValueError
        A value whose ``repr`` is not a Python literal giving it back (a non-finite
        float, an object), naming the parameter.
    """
    lines = ["# Parameters (injected by python -m uwbwb reproduce)"]
    for name, value in parameters.items():
        if not name.isidentifier():
            raise ValueError(f"parameter name {name!r} is not a Python identifier")
        literal = repr(value)
        try:
            back = ast.literal_eval(literal)
        except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
            back = _MISSING
        if back is _MISSING or type(back) is not type(value) or back != value:
            raise ValueError(f"parameter {name}={literal[:60]}: not a Python literal that reads back as itself")
        lines.append(f"{name} = {literal}")
    return "\n".join(lines) + "\n"


def parameterized(nb, parameters: Mapping[str, Any]):
    """``nb`` (a notebook node, changed in place and returned) with the injected parameters cell
    right after its ``parameters`` cell (replacing an injected cell already there)."""
    import nbformat          # imported when used: it costs seconds, and parameters are checked before any run

    cells = [c for c in nb.cells if INJECTED_TAG not in c.metadata.get("tags", [])]
    where = next((i + 1 for i, c in enumerate(cells) if "parameters" in c.metadata.get("tags", [])), 0)
    cell = nbformat.v4.new_code_cell(injected_source(parameters))
    cell.metadata["tags"] = [INJECTED_TAG]
    nb.cells = cells[:where] + [cell] + cells[where:]
    meta = nb.metadata.setdefault("papermill", {})
    meta["parameters"] = json.loads(json.dumps(dict(parameters), default=repr))   # JSON record (tuples as lists)
    return nb
