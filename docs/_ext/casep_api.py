"""Sphinx extension: the API reference pages, written from the packages' ``__all__``.

One page per public module (``reference/api/<module>.rst``, generated before the sources are
read, not committed). Each object is documented once, on the page of the first module in
:data:`PUBLIC_MODULES` that exports it; the ``casep`` page lists every name of ``casep.__all__``
and documents there only those that no subpackage exports (``separate``, ``fuse``, ...). A name
added to an ``__all__`` appears in the reference without editing the docs.
"""

from __future__ import annotations

import importlib
import inspect
import shutil
from pathlib import Path

#: Public modules in the order their pages appear; ``casep`` itself comes first in the index.
PUBLIC_MODULES = (
    "casep.model",
    "casep.io",
    "casep.noise",
    "casep.regression",
    "casep.checks",
    "casep.estimators",
    "casep.simulation",
    "casep.impact",
    "casep.design",
    "casep.montecarlo",
    "casep.calibration",
    "casep.radar",
    "casep.navigation",
    "casep.frames",
    "casep.gravity",
    "casep.rotations",
    "casep.units",
    "casep.exceptions",
    "casep.results",
)


def _public_names(module) -> list[str]:
    return [n for n in getattr(module, "__all__", []) if not n.startswith("_")]


def _page(modname: str, title: str, documented: list[str], linked: list[str]) -> str:
    lines = [title, "=" * len(title), "", f".. automodule:: {modname}", "   :no-members:", "",
             f".. currentmodule:: {modname}", ""]
    if documented:
        lines += [".. autosummary::", "   :toctree: generated", ""]
        lines += [f"   {name}" for name in documented]
        lines.append("")
    if linked:
        lines += ["Also available here, documented where they are defined:", "",
                  ".. list-table::", "   :widths: 30 70", ""]
        for target, summary in linked:
            lines += [f"   * - :py:obj:`~{target}`", f"     - {summary}"]
        lines.append("")
    return "\n".join(lines)


def _summary(obj) -> str:
    """First sentence of `obj`'s own docstring (none for plain data)."""
    if isinstance(obj, (int, float, str, tuple, dict, list)):
        return ""
    doc = inspect.getdoc(obj) or ""
    first = doc.strip().split("\n\n")[0].replace("\n", " ")
    return first.split(". ")[0].rstrip(".") + "." if first else ""


def write_api_pages(outdir: Path) -> list[str]:
    """Write one ``.rst`` page per public module into `outdir`; return the page names.

    Pages and autosummary stubs of names no longer public are removed first, so that a renamed
    or removed name leaves no orphan page behind (an orphan is a build warning).
    """
    outdir.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(outdir / "generated", ignore_errors=True)
    home: dict[int, str] = {}  # id(object) -> full name where it is documented
    pages: dict[str, tuple[list[str], list[str]]] = {}
    for modname in PUBLIC_MODULES:
        module = importlib.import_module(modname)
        documented, linked = [], []
        for name in _public_names(module):
            obj = getattr(module, name)
            key = id(obj)
            # Numbers and strings are shared by identity (small ints, interned strings): a
            # constant is documented in every module that exports it under its own name.
            if key in home and not isinstance(obj, (int, float, str, tuple, dict, list)):
                linked.append((home[key], _summary(obj)))
            else:
                home.setdefault(key, f"{modname}.{name}")
                documented.append(name)
        pages[modname] = (documented, linked)
    top = importlib.import_module("casep")
    documented, linked = [], []
    for name in _public_names(top):
        if name == "__version__":
            continue
        obj = getattr(top, name)
        if id(obj) in home:
            linked.append((home[id(obj)], _summary(obj)))
        else:
            documented.append(name)
    names = ["casep"] + list(PUBLIC_MODULES)
    texts = {"casep": _page("casep", "casep", documented, linked)}
    for modname in PUBLIC_MODULES:
        texts[modname] = _page(modname, modname, *pages[modname])
    for stale in outdir.glob("*.rst"):
        if stale.stem not in texts and stale.stem != "index":
            stale.unlink()
    for modname, text in texts.items():
        path = outdir / f"{modname}.rst"
        if not path.exists() or path.read_text() != text:  # unchanged pages keep their mtime
            path.write_text(text)
    index = ["API reference", "=============", "",
             "Generated from the docstrings of the public names: ``casep.__all__`` and the",
             "``__all__`` of each public subpackage. Private modules (a leading underscore) are not",
             "part of the API.", "", ".. toctree::", "   :maxdepth: 1", ""]
    index += [f"   {n}" for n in names]
    text = "\n".join(index) + "\n"
    path = outdir / "index.rst"
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return names


def _config_inited(app, config) -> None:
    write_api_pages(Path(app.srcdir) / "reference" / "api")


def setup(app):
    # At config-inited, before Sphinx lists the sources and autosummary generates the stubs
    # these pages ask for.
    app.connect("config-inited", _config_inited)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
