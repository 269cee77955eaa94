"""The README's table names every command of the command line, so a reader finds each one from it."""

from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_names_every_command():
    from casep.cli import build_parser

    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    text = README.read_text(encoding="utf-8")
    assert len(commands) >= 12
    missing = [c for c in commands if f"casep {c}" not in text]
    assert not missing, f"the README does not name: {', '.join(f'casep {c}' for c in missing)}"
    # the input kinds of `casep separate` beyond a flight file: tracking, Earth-fixed tracking, radar
    assert all(opt in text for opt in ("--radar", "read_flight_pair", "--noise --robust"))
