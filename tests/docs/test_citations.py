"""What the code, docs and bundled files cite is something a user has: docs/formats.md, never the project's
private contract file or the shared folder it lives in (issue 47: the bundled robot TOMLs cited it)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: written in two parts so that this file does not hold what it looks for
PRIVATE = ("INTERFACE" + ".md", "../" + "shared")
SUFFIXES = {".py", ".md", ".toml", ".txt", ".csv", ".json", ".cfg", ".ini", ".yml", ".yaml", ".sh"}
FOLDERS = ("casadical", "docs", "problems", "benchmarks", "examples", "tests")


def _files():
    yield from (ROOT / name for name in ("README.md", "pyproject.toml") if (ROOT / name).is_file())
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*")):
            if path.is_file() and path.suffix in SUFFIXES and ".venv" not in path.parts and path.stat().st_size < 2e6:
                yield path


def test_no_citation_of_a_file_users_do_not_have():
    found = []
    for path in _files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for n, line in enumerate(text.splitlines(), 1):
            found += [f"{path.relative_to(ROOT)}:{n}: {line.strip()}" for p in PRIVATE if p in line]
    assert found == [], "cite docs/formats.md instead:\n" + "\n".join(found)
