"""The README and the docs/ pages stay true: every `ctsim` command they show parses with ctsim's own
parser (the cheap listings run), every repository file a command names exists, the README shows
each file of its own before a command uses it, its Python runs, its test command is `.ci/run`'s,
and every link between the pages resolves (to a file, and to a heading where it names one)."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from sim.cli.entry import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md")), ROOT / "worlds" / "README.md"]
FOLDERS = ("worlds/", "tests/", "docs/", "bench/", "sim/", "bots/")
"""A command's argument starting with one of these names a file of the repository."""
CHEAP = (["worlds"], ["controllers"])
"""Listings that run in a moment: run for real, not only parsed."""


def _shell_lines(text: str) -> list[tuple[int, str]]:
    """(offset in the page, line) of every line of the page's ```sh blocks, continuations joined."""
    found = []
    for block in re.finditer(r"```sh\n(.*?)```", text, re.S):
        joined = block.group(1).replace("\\\n", " ")
        found += [(block.start(), line) for line in joined.splitlines() if line.strip()]
    return found


def _inline_commands(text: str) -> list[tuple[int, str]]:
    """(offset, command) of every inline code span that is a `ctsim ...` command (a bare `ctsim lab`
    names the tool in a sentence)."""
    return [(m.start(), m.group(1)) for m in re.finditer(r"`(ctsim [^`\s]+ [^`]+)`", text)]


def commands(page: Path) -> list[tuple[int, list[str]]]:
    """Every command a page shows, as words (comments dropped, `a && b` and `a | b` apart)."""
    text = page.read_text(encoding="utf-8")
    found = []
    for at, line in _shell_lines(text) + _inline_commands(text):
        words = shlex.split(line, comments=True)
        part: list[str] = []
        for word in [*words, "&&"]:
            if word in ("&&", "|", "||", ";"):
                if part:
                    found.append((at, part))
                part = []
            else:
                part.append(word)
    return found


def _ctsim_commands() -> list[tuple[str, list[str]]]:
    shown = []
    for page in PAGES:
        for _, words in commands(page):
            if Path(words[0]).name == "ctsim" and not (len(words) > 1 and words[1].isupper()):  # `ctsim COMMAND --help`
                shown.append((page.relative_to(ROOT).as_posix(), words[1:]))
    return shown


SHOWN = _ctsim_commands()


def test_the_pages_show_commands():
    assert len(SHOWN) > 40 and {page for page, _ in SHOWN} >= {"README.md", "docs/bridge.md", "docs/lab.md", "docs/contest.md", "docs/experiments.md"}


@pytest.mark.parametrize(("page", "argv"), SHOWN, ids=[f"{page}: ctsim {' '.join(argv)}"[:90] for page, argv in SHOWN])
def test_every_shown_command_parses(page, argv):
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
        try:
            build_parser().parse_args(argv)
        except SystemExit as done:
            assert done.code == 0, f"{page}: `ctsim {' '.join(argv)}` no longer parses: {stderr.getvalue().strip()}"
    for word in argv:  # WORLD, FILE.py:Class, NAME=firmware:PATH,KEY=VALUE
        path = (word.partition("=")[2] or word).removeprefix("firmware:").partition(",")[0]
        path = path.split(".py:")[0] + ".py" if ".py:" in path else path
        if path.startswith(FOLDERS):
            assert (ROOT / path).exists(), f"{page}: {path} does not exist"


@pytest.mark.parametrize("argv", CHEAP)
def test_the_shown_listings_run(argv, capsys):
    assert any(shown == argv for _, shown in SHOWN)
    assert main(argv) == 0 and capsys.readouterr().out.strip()


def test_the_readmes_world_check_runs(capsys):
    (argv,) = [argv for page, argv in SHOWN if page == "README.md" and argv[0] == "check"]
    assert main([argv[0], str(ROOT / argv[1])]) == 0 and capsys.readouterr().out.startswith("OK")


def test_every_python_script_a_page_runs_exists():
    for page in PAGES:
        for _, words in commands(page):
            if Path(words[0]).name in ("python", "python3") and len(words) > 1 and words[1].endswith(".py"):
                assert (ROOT / words[1]).is_file(), f"{page.name}: {words[1]} does not exist"


def test_the_readme_shows_each_file_before_a_command_uses_it():
    text = README.read_text(encoding="utf-8")
    shown = {m.group(1): m.start() for m in re.finditer(r"```\w*\n# (\S+)\n", text)}
    for at, line in _shell_lines(text) + _inline_commands(text):
        for word in shlex.split(line, comments=True):
            name = word.partition(".py:")[0] + ".py" if ".py:" in word else word
            if name.endswith((".py", ".toml")) and not (ROOT / name).exists():
                assert name in shown and shown[name] < at, f"README: `{line}` uses {name} before (or without) showing it"


def test_the_readmes_python_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    assert len(blocks) == 2
    for block in blocks:
        exec(compile(block, str(README), "exec"), {"__name__": "__main__"})


def test_the_readmes_test_command_is_the_ci_s():
    """`.ci/run` runs the README's test command: the same steps, in order, pytest last (it may
    install more between them)."""
    (readme,) = [line for _, line in _shell_lines(README.read_text(encoding="utf-8")) if "-m pytest" in line]
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if "-m pytest" in line][-1]
    steps, ci_steps = [s.strip() for s in readme.split("&&")], [s.strip() for s in ci.split("&&")]
    assert steps[-1] == ci_steps[-1] == ".venv/bin/python -m pytest"
    assert [s for s in ci_steps if s in steps] == steps


def _slug(heading: str) -> str:
    """A heading's anchor as GitHub makes it."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return {_slug(m.group(1)) for m in re.finditer(r"^#+ (.+)$", text, re.M)}


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_every_link_resolves(page):
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):  # https: and the like: outside the repository
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        assert file.exists(), f"{page.name}: link to {target}: no such file"
        if anchor:
            assert anchor in _anchors(file), f"{page.name}: link to {target}: no such heading"


def test_the_readme_is_a_front_door():
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 200
