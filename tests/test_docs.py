"""The README and the documentation sources: what a user copies works, the docs cover the API.

The documentation build itself (Sphinx, warnings as errors) runs in ``.ci/run``; these checks are
the cheap ones that fail early in the test suite.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _code_blocks(text: str, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_is_short_and_starts_with_the_two_commands():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    first = _code_blocks(text, "")[0].splitlines()
    assert first == ["python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/casep demo",
                     'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && .venv/bin/python -m pytest']
    # .ci/run runs exactly the README's test command first
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if line and not line.startswith("#")]
    assert first[1] in ci[ci.index('cd "$(dirname "$0")/.."') + 1]


def test_readme_python_example_runs(tmp_path):
    (code,) = _code_blocks(README.read_text(encoding="utf-8"), "python")
    assert len(code.strip().splitlines()) <= 12
    script = tmp_path / "example.py"
    script.write_text("import warnings\nwarnings.simplefilter('ignore')\n" + code
                      + "\nassert set(crlb) == set(df.index) and doc['method'] == 'ols' and groups\n")
    run = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "Ka0x" in run.stdout


def test_readme_links_point_to_files_in_the_repository():
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert links
    missing = [link for link in links if not link.startswith("http") and not (ROOT / link).exists()]
    assert not missing


@pytest.mark.parametrize("folder", ["guide", "results"])
def test_every_docs_page_starts_with_a_title(folder):
    pages = sorted((ROOT / "docs" / folder).glob("*.md"))
    assert pages
    for page in pages:
        first = page.read_text(encoding="utf-8").lstrip().splitlines()[0]
        assert first.startswith("# "), f"{page.relative_to(ROOT)} does not start with a '# Title' line"


def test_api_pages_cover_every_public_name(tmp_path):
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        import casep_api
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))
    import casep

    pages = casep_api.write_api_pages(tmp_path)
    text = "\n".join((tmp_path / f"{p}.rst").read_text() for p in pages)
    for name in casep.__all__:
        if name != "__version__":
            assert re.search(rf"(^   {name}$|\.{name}`)", text, flags=re.M), name
    # each module's own names are documented on its page
    for module in casep_api.PUBLIC_MODULES:
        page = (tmp_path / f"{module}.rst").read_text()
        assert f".. automodule:: {module}" in page


def test_cli_reference_parser_has_every_command():
    from casep.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert {"separate", "diagnose", "simulate", "montecarlo", "demo", "models", "methods", "impact",
            "design", "fuse", "noise", "calibrate"} <= set(sub.choices)
