"""Every command of the guide pages, the documentation's index and reference pages and the README runs.

A page's command blocks run in order, one page per test case, in a fresh directory holding the
repository's ``examples/``, ``models/`` and ``tests/data/`` (links) and the files a page asks the
reader to have (:data:`READER_FILES`), with ``casep`` on the PATH. A block is a command block when
its fence says ``console``, ``bash`` or ``shell``, or when it has no language and every line reads
as a command of ``casep``, ``python``, ``pip`` or ``.venv/bin/`` without a placeholder (a synopsis
such as ``casep impact FLIGHT --result RESULT.json [--top K]``, or a ``text`` block of commands, is
not run; its options are checked against the parser instead).

Each command must exit 0; the last command of a block preceded by a line ``<!-- exit N -->`` must
exit N (a block that shows a refusal); a command may print only the warnings of
:data:`EXPECTED_WARNINGS`. A block preceded by ``<!-- output -->`` is the output of the last
command before it: its lines must be printed, in order (``...`` skips lines, a line ending in
``...`` is a prefix). Slow commands run reduced, each rewrite in :data:`REWRITES` with its
reason; a rewrite that matches no command fails the test, so the table cannot go stale.

A page's first ``casep`` command runs as the reader's shell runs it: ``bash -c``, the ``casep`` script, a new
interpreter. Its later plain ``casep`` commands (no shell syntax: the shell would pass ``shlex.split``'s words)
call the entry point :func:`casep.cli.main` with those words in a forked child of this process, with the
reader's directory, environment and Python's default warning filters, and exit with its status as
``sys.exit`` would: the same command, without the 1.2-1.5 s of CPU of a new interpreter importing casep.
"""

from __future__ import annotations

import functools
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import run_forked

ROOT = Path(__file__).resolve().parents[2]
# The reader's pages; docs/results/ is left out: its commands are the benchmarks behind the measured
# tables (minutes each), which the results pages re-run by hand.
PAGES = [*sorted((ROOT / "docs" / "guide").glob("*.md")), ROOT / "docs" / "index.md",
         *sorted((ROOT / "docs" / "reference").glob("*.md")), ROOT / "README.md"]
RUN_LANGUAGES = ("console", "bash", "shell")
COMMAND_WORDS = ("casep ", "python3 ", "python ", "pip ", ".venv/bin/")

#: Commands run otherwise here, each with the reason: ``None`` leaves the command out.
REWRITES: dict[str, tuple[str | None, str]] = {
    "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/casep demo":
        ("casep demo --rate 10", "the install is the environment of this test; the demo at 10 Hz instead of "
                                 "100 Hz, as tests/workflows/test_demo.py runs it (4 s instead of 8 s)"),
    'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && .venv/bin/python -m pytest':
        (None, "the test suite itself: .ci/run runs this line verbatim (tests/test_docs.py checks that)"),
    '.venv/bin/pip install -e ".[docs]" && .venv/bin/sphinx-build -W --keep-going -b html docs docs/_build/html':
        (None, ".ci/run builds the documentation with this sphinx-build line"),
    'pip install -e ".[docs]" && sphinx-build -W --keep-going -b html docs docs/_build/html':
        (None, "the same build, as docs/reference/layout.md gives it: .ci/run builds the documentation"),
    "casep simulate -o tel.csv --rate 20 --rotating-earth --launch-site 28.5 -80.6 3 90 --radar-station S1.json "
    "--radar-station S2.json --tracking-truth trk.json":
        ("casep simulate -o tel.csv --rate 10 --radar-rate 5 --rotating-earth --launch-site 28.5 -80.6 3 90 "
         "--radar-station S1.json --radar-station S2.json --tracking-truth trk.json",
         "the radar page's flight at 10 Hz with radar at 5 Hz instead of 20 and 20: its three separations "
         "then take 14 s of CPU instead of 23 (tests/radar/ runs the full rates)"),
}

#: Commands that read nothing a page wrote before them and write only their own folder: run once for every
#: page that shows them (per test process), with the reason.
RUN_ONCE = {"casep demo --rate 10": "it simulates its own flight and writes only casep-demo/; three pages show it"}

#: Files a page tells the reader to write and shows in full, present for every page (each content must
#: stand verbatim on a page: a file the page does not show would hide a command the reader cannot run).
#: The radar page writes its station files itself, in its simulation block.
READER_FILES: dict[str, str] = {}
#: A page's own flight: `flight.csv` in a command is the reader's flight; here the shipped one.
READER_COPIES = {"flight.csv": ROOT / "examples" / "data" / "example_flight.csv"}
#: Warnings a page's command may print, each with the reason; any other fails (a documented command that
#: warns is a page to fix, or a warning to explain here and on the page).
EXPECTED_WARNINGS = {
    "ill-conditioned regression": "a boost flight determines combinations of coefficients, not each one: "
                                  "first-flight.md shows and explains it",
    "the navigation is curved at one std": "a MEMS IMU's poorly determined combinations are degrees of attitude "
                                           "at one std: navigate.md shows the warning and explains it",
    "the record determines ": "a MEMS IMU's roll-axis gyro combinations have std 4-20 times the plausible size of its "
                              "errors and are left at the prior: navigate.md shows the warning and explains it",
    "the record does not bound the tracking noise's correlation time": "a 40 s MEMS launch's tracking holds one "
        "axis's correlation time from 1.3 s up to the record length: navigate.md shows the warning and explains it",
    "the navigation is not linear over what the flight does not determine": "a MEMS IMU's combinations left at the "
        "prior move the ones stated by their second order: navigate.md shows the warning and explains it",
}
_WARNING = re.compile(r"^(?:warning: |\S*Warning: )(.*)$", re.M)

#: Blocks run first on a page (a substring of the block), with the reason.
RUN_FIRST = {"radar.md": ("casep simulate -o tel.csv", "the opening example separates the files that the "
                                                      "page's simulation writes, as the page says")}

_FENCE = re.compile(r"^(?P<fence>```+)(?P<lang>[^\n`]*)\n(?P<body>.*?)^(?P=fence)[ \t]*$", re.M | re.S)
_EXIT = re.compile(r"<!--\s*exit\s+(\d+)\s*-->\s*$")
_OUTPUT = re.compile(r"<!--\s*output\s*-->\s*$")
# a placeholder: options in brackets, alternatives, an ellipsis, or an upper-case name of two letters or
# more (FLIGHT, TEL.csv, RESULT_A.json)
_PLACEHOLDER = re.compile(r"^\[|^\.\.\.|(?<![\w.-])[A-Z]{2,}[A-Z0-9_]*(?:\.\w+)?(?![\w-])|\w\|\w")


@dataclass
class Block:
    page: str
    line: int
    lang: str
    commands: list[str]
    exit: int = 0
    shown: list[str] = field(default_factory=list)  # the output the page shows for the block's last command


def _commands(body: str) -> list[str]:
    """The block's commands: lines joined at a trailing backslash, blank lines and comment lines dropped."""
    out: list[str] = []
    for line in re.sub(r"[ \t]*\\\n\s*", " ", body).splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            out.append(line.strip())
    return out


def _is_synopsis(command: str) -> bool:
    try:
        words = shlex.split(command, comments=True)
    except ValueError:  # an unbalanced quote: not a shell command a reader could run as it stands
        return True
    return any(_PLACEHOLDER.search(w) for w in words[1:] if not w.startswith("--"))


def blocks(page: Path) -> tuple[list[Block], list[Block]]:
    """The page's command blocks to run, and its synopses (command lines with placeholders, not run)."""
    text = page.read_text(encoding="utf-8")
    run, synopses = [], []
    for m in _FENCE.finditer(text):
        lang = m["lang"].strip()
        line = text.count("\n", 0, m.start()) + 1
        cmds = _commands(m["body"])
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        status = int(_EXIT.search(before)[1]) if _EXIT.search(before) else 0
        block = Block(page.name, line, lang, cmds, status)
        if _OUTPUT.search(before):  # the output of the last command run before it on the page
            assert run, f"{page.name}:{line}: an output block with no command before it"
            run[-1].shown = m["body"].splitlines()
            continue
        if lang in RUN_LANGUAGES:
            run.append(block)
        elif lang in ("", "text") and cmds and all(c.startswith(COMMAND_WORDS) for c in cmds):
            (synopses if any(_is_synopsis(c) for c in cmds) or lang == "text" else run).append(block)
    first = RUN_FIRST.get(page.name)
    if first:
        run.sort(key=lambda b: not any(first[0] in c for c in b.commands))
    return run, synopses


def _missing_output(shown: list[str], out: str) -> list[str]:
    """The lines of `shown` not in `out`, in order (spaces collapsed; ``...`` skips, a trailing ``...``: a prefix)."""
    got = [" ".join(line.split()) for line in out.splitlines()]
    k, missing = 0, []
    for line in (" ".join(x.split()) for x in shown):
        if line in ("", "..."):
            continue
        prefix = line.endswith("...")
        want = line[:-3].rstrip() if prefix else line
        hit = next((j for j in range(k, len(got)) if (got[j].startswith(want) if prefix else got[j] == want)), None)
        if hit is None:
            missing.append(line)
        else:
            k = hit + 1
    return missing


def _pages_with_commands() -> list[Path]:
    return [p for p in PAGES if blocks(p)[0]]


def _workdir(tmp_path: Path) -> dict[str, str]:
    """The reader's directory and environment: repository data linked, reader files written, casep on PATH."""
    for name in ("examples", "models"):
        (tmp_path / name).symlink_to(ROOT / name)
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "data").symlink_to(ROOT / "tests" / "data")
    for name, content in READER_FILES.items():
        (tmp_path / name).write_text(content)
    for name, src in READER_COPIES.items():
        (tmp_path / name).write_bytes(src.read_bytes())
    bindir = tmp_path / "bin"
    bindir.mkdir()
    # the installed entry point's own code, run by this interpreter (a venv or not)
    (bindir / "casep").write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m casep "$@"\n')
    (bindir / "casep").chmod(0o755)
    env = dict(os.environ)
    env.update(PATH=f"{bindir}{os.pathsep}{env.get('PATH', '')}", OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               MPLBACKEND="Agg")
    return env


def _run(cmd: str, cwd: Path, env: dict[str, str]) -> tuple[int, str, str]:
    proc = subprocess.run(["bash", "-c", cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=300,
                          check=False)
    return proc.returncode, proc.stdout, proc.stderr


#: Characters that make a command more than a list of words to the shell (operators, expansions, quoting escapes):
#: a command holding one runs in the shell.
_SHELL_SYNTAX = re.compile(r"[|&;<>()$`*?~\[\]{}\\!=]")


def _casep_words(cmd: str) -> list[str] | None:
    """The arguments the shell would pass to ``casep`` for `cmd`, or None when `cmd` is not one plain casep command."""
    words = shlex.split(cmd, comments=True)
    if words[:1] != ["casep"] or any(_SHELL_SYNTAX.search(w) for w in words):
        return None
    return words[1:]


def _run_main(argv: list[str], cwd: Path, env: dict[str, str]) -> tuple[int, str, str]:
    """``casep ARGV`` run by the entry point :func:`casep.cli.main` in a forked child (:func:`conftest.run_forked`)."""
    from casep.cli import main

    return run_forked(lambda: main(argv), ["casep", *argv], cwd, env)


@functools.cache
def _run_once(cmd: str) -> tuple[int, str, str]:
    folder = Path(tempfile.mkdtemp(prefix="casep-docs-"))
    try:
        return _run(cmd, folder, _workdir(folder))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _rewrite(command: str) -> str | None:
    return REWRITES[command][0] if command in REWRITES else command


@pytest.mark.parametrize("page", _pages_with_commands(), ids=lambda p: p.name)
def test_page_commands_run(page: Path, tmp_path: Path):
    env = _workdir(tmp_path)
    shell_run = False  # a casep command of the page has run in the shell
    for block in blocks(page)[0]:
        cmds = [c for c in map(_rewrite, block.commands) if c is not None]
        for k, cmd in enumerate(cmds):
            expected = block.exit if k == len(cmds) - 1 else 0
            words = _casep_words(cmd)
            if cmd in RUN_ONCE:
                code, out, err = _run_once(cmd)
            elif words is not None and shell_run:
                code, out, err = _run_main(words, tmp_path, env)
            else:
                code, out, err = _run(cmd, tmp_path, env)
                shell_run = shell_run or words is not None
            assert code == expected, (f"{page.name}:{block.line}: `{cmd}` exited {code}, the page says {expected}\n"
                                      f"{out[-1500:]}\n{err[-1500:]}")
            warned = [w for w in _WARNING.findall(out + err)
                      if not any(w.startswith(k) for k in EXPECTED_WARNINGS)]
            # a block that shows a failure (exit N) may warn on the way: the page explains the failure
            assert not warned or expected != 0, f"{page.name}:{block.line}: `{cmd}` warns: {warned}"
        missing = _missing_output(block.shown, out + err) if block.shown else []
        assert not missing, f"{page.name}:{block.line}: `{cmds[-1]}` does not print the page's lines {missing}\n{out}"


def test_the_pages_are_found_and_hold_commands():
    names = {p.name for p in _pages_with_commands()}
    assert {"README.md", "first-flight.md", "calibration.md", "radar.md", "simulation.md"} <= names


def test_every_rewrite_and_first_block_is_used():
    commands = {c for p in PAGES for b in blocks(p)[0] for c in b.commands}
    stale = [c for c in REWRITES if c not in commands]
    assert not stale, f"REWRITES entries that match no command of the pages: {stale}"
    rewritten = {_rewrite(c) for c in commands}
    assert set(RUN_ONCE) <= rewritten, f"RUN_ONCE entries that match no command: {set(RUN_ONCE) - rewritten}"
    for page, (first, _) in RUN_FIRST.items():
        (path,) = [p for p in PAGES if p.name == page]
        assert any(first in c for c in blocks(path)[0][0].commands), f"{page}: no block with {first!r}"


def test_every_reader_file_is_shown_in_full_on_a_page():
    text = "\n".join(p.read_text(encoding="utf-8") for p in PAGES)
    hidden = [name for name, content in READER_FILES.items() if content.strip() not in text]
    assert not hidden, f"files the test writes that no page shows in full: {hidden}"


def test_a_console_block_holds_no_placeholder():
    bad = [f"{p.name}:{b.line}: {c}" for p in PAGES for b in blocks(p)[0] if b.lang in RUN_LANGUAGES
           for c in b.commands if c.startswith("casep ") and _is_synopsis(c)]
    assert not bad, f"a console block is run: write a synopsis as a ```text block instead: {bad}"


def test_synopsis_options_exist():
    """Each ``--option`` of a ``casep <command>`` synopsis is an option of that command's parser."""
    from casep.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    unknown = []
    for page in PAGES:
        for block in blocks(page)[1]:
            for cmd in block.commands:
                words = cmd.split()
                if words[0] != "casep" or len(words) < 2 or words[1] not in sub:
                    continue
                known = set(sub[words[1]]._option_string_actions)
                for opt in re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", cmd.split(" #")[0]):
                    if opt not in known:
                        unknown.append(f"{page.name}:{block.line}: casep {words[1]} {opt}")
    assert not unknown, f"options the parser does not have: {unknown}"


def test_the_block_rules(tmp_path):
    """What is run, with which status and shown output, and what is a synopsis, on a page made for it."""
    page = tmp_path / "page.md"
    page.write_text("# Page\n\n```console\ncasep models \\\n   --json m.json  # listed\n```\n\n"
                    "```\ncasep impact FLIGHT --result RESULT.json [--top K]\n```\n\n"
                    "<!-- exit 2 -->\n```\ncasep separate no.csv\n```\n\n"
                    "<!-- output -->\n```text\ncasep: error: ...\n```\n\n"
                    "```text\ncasep separate flight.csv\n```\n\n```python\nimport casep\n```\n\n"
                    '```\npython3 -m pip install -e ".[test]"\n```\n')
    run, synopses = blocks(page)
    assert [(b.line, b.commands, b.exit) for b in run] == [
        (3, ["casep models --json m.json  # listed"], 0), (13, ["casep separate no.csv"], 2),
        (30, ['python3 -m pip install -e ".[test]"'], 0)]
    assert run[1].shown == ["casep: error: ..."] and not run[0].shown
    assert [b.line for b in synopses] == [8, 22]


def test_a_plain_casep_command_runs_as_in_the_shell(tmp_path):
    """The forked entry point gives the shell's exit status and output (a refusal here: exit 2, one line);
    a command with shell syntax is left to the shell."""
    env = _workdir(tmp_path)
    assert _casep_words("casep separate flight.csv --robust  # Huber always") == ["separate", "flight.csv", "--robust"]
    assert _casep_words("casep 'a b' --json m.json") == ["a b", "--json", "m.json"]
    for cmd in ("casep models | head -1", "casep separate *.csv", "casep models > m.txt", "X=1 casep models",
                "echo casep", "casep separate $HOME/f.csv"):
        assert _casep_words(cmd) is None, cmd
    cmd = "casep separate no.csv --json out.json"
    shell, forked = _run(cmd, tmp_path, env), _run_main(_casep_words(cmd), tmp_path, env)
    assert shell[0] == 2 and "casep: error:" in shell[2] and forked == shell
    assert not (tmp_path / "out.json").exists()
