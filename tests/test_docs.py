"""The pages, the code and the tests describe the software as it is (no history of its making,
no private run folders), a README short enough to read, and every ``fingertip`` command the
pages show one that the real command line accepts (parsed by its own parser, never run)."""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from explore.cli import _SUBCOMMANDS, build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: the pages a user reads; none may speak of how or when the software was made
USER_PAGES = [
    README,
    ROOT / "CHANGELOG.md",
    *sorted((ROOT / "docs").glob("*.md")),
    ROOT / "datasets/README.md",
    ROOT / "surrogate/README.md",
]
#: words of the project's own making (bracketed letters: this line does not match itself)
HISTORY = re.compile(
    r"[Ss]essions? [0-9]+|[Tt]his sessio[n]|betwee[n] sessions|wor[k] session|runs/main_v[0-9]+"
)
#: the code and tests, held to the same rule as the pages
SOURCES = sorted(
    p
    for d in ("sim", "explore", "surrogate", "tests", "studies", "benchmarks")
    for p in (ROOT / d).rglob("*.py")
)
MAX_README_WORDS = 1500  # the issue: "about 1 500 words at most"
#: the languages of fenced blocks whose lines are shell commands ("": none given)
SHELL = {"", "bash", "sh", "shell", "console"}
SEPARATORS = {"&&", "||", ";", "|"}


@pytest.mark.parametrize("page", [*USER_PAGES, *SOURCES], ids=lambda p: str(p.relative_to(ROOT)))
def test_no_history_of_its_making_or_private_run_folders(page: Path) -> None:
    hits = [
        f"{page.relative_to(ROOT)}:{n}: {line.strip()}"
        for n, line in enumerate(page.read_text().splitlines(), 1)
        if HISTORY.search(line)
    ]
    assert not hits, "speak of the software as it is:\n" + "\n".join(hits)


def test_the_readme_is_short() -> None:
    words = len(README.read_text().split())
    assert words <= MAX_README_WORDS, f"README.md has {words} words (at most {MAX_README_WORDS})"


def shell_blocks(text: str) -> list[str]:
    """The fenced code blocks of ``text`` in a shell language (or none), fence by fence."""
    blocks, language, lines = [], None, []
    for line in text.splitlines():
        if line.startswith("```"):
            if language is None:
                language, lines = line[3:].strip(), []
            else:
                if language in SHELL:
                    blocks.append("\n".join(lines))
                language = None
        elif language is not None:
            lines.append(line)
    return blocks


def fingertip_commands(text: str) -> list[list[str]]:
    """The arguments of every ``fingertip ...`` command in the shell code blocks of ``text``
    (continued lines joined, comments dropped, split at ``&&``, ``;`` and pipes)."""
    commands = []
    for block in shell_blocks(text):
        for line in block.replace("\\\n", " ").splitlines():
            try:
                words = shlex.split(line, comments=True)
            except ValueError:  # prose in an unlabelled block: an apostrophe
                assert "fingertip " not in line, f"cannot parse {line!r}"
                continue
            start = 0
            for i, word in enumerate([*words, ";"]):
                if word in SEPARATORS:
                    part = words[start:i]
                    if part and part[0] == "fingertip":
                        commands.append(part[1:])
                    start = i + 1
    return commands


def _subparser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices[name]


def check_command(argv: list[str]) -> None:
    """Parse ``fingertip *argv`` with the CLI's own parser (nothing runs): the subcommand must
    exist and take every option given, spelt in full (argparse would accept a prefix)."""
    shown = "fingertip " + " ".join(argv)
    if argv and not argv[0].startswith("-"):
        assert argv[0] in _SUBCOMMANDS, f"{shown}: no subcommand {argv[0]!r}"
    parser = build_parser(argv[0] if argv and argv[0] in _SUBCOMMANDS else "")
    if argv and argv[0] in _SUBCOMMANDS:
        known = _subparser(parser, argv[0])._option_string_actions
        for word in argv[1:]:
            if word.startswith("--"):
                option = word.split("=", 1)[0]
                assert option in known, f"{shown}: {argv[0]} has no option {option}"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            parser.parse_args(argv)
        except SystemExit as exc:
            assert exc.code == 0, f"{shown}: {err.getvalue().strip()}"


def test_readme_commands_are_real_subcommands_and_options() -> None:
    commands = fingertip_commands(README.read_text())
    # the set-up command's main job and the examples of the other subcommands
    assert {argv[0] for argv in commands if argv} >= {"run", "simulate"}
    for argv in commands:
        check_command(argv)


def test_the_command_check_catches_what_it_should() -> None:
    text = (
        "```toml\nx = 1\n```\nprose, with fingertip run's quote\n"
        "```bash\nfingertip simulate d.toml --protocl plate  # a typo\nls && fingertip nope\n```\n"
    )
    bad_option, bad_command = fingertip_commands(text)
    assert bad_option == ["simulate", "d.toml", "--protocl", "plate"]
    assert bad_command == ["nope"]
    for argv in (bad_option, bad_command, ["simulate", "--prot", "plate"], ["run", "--n", "x"]):
        with pytest.raises(AssertionError):
            check_command(argv)
    check_command(["simulate", "d.toml", "--protocol", "plate", "--set", "wedge.hold_s=50"])


DOC_PAGES = [
    *sorted((ROOT / "docs").glob("*.md")),
    ROOT / "datasets/README.md",
    ROOT / "surrogate/README.md",
]


@pytest.mark.parametrize("page", DOC_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_doc_commands_are_real_with_real_options_and_files(page: Path) -> None:
    """Every ``fingertip`` command in a page's shell blocks parses with the CLI's own parser;
    each ``--set SECTION.FIELD=VALUE`` names a real option; each repository file it names
    (``docs/...``, ``sim/...``, ``datasets/...``, ``surrogate/...``) exists."""
    from sim.options import option_names

    known = set(option_names())
    for argv in fingertip_commands(page.read_text()):
        check_command(argv)
        for flag, value in zip(argv, [*argv[1:], ""], strict=True):
            if flag == "--set":
                name = value.split("=", 1)[0]
                assert name in known, f"{page.name}: fingertip {' '.join(argv)}: no option {name}"
        for word in argv:
            if word.startswith(("docs/", "sim/", "datasets/", "surrogate/")) and "*" not in word:
                assert (ROOT / word).exists(), f"{page.name}: {word} does not exist"


@pytest.mark.parametrize(
    "path",
    sorted((ROOT / "docs").glob("*/*.toml")),
    ids=lambda p: f"{p.parent.name}/{p.name}",
)
def test_the_design_files_in_the_docs_load(path: Path) -> None:
    """The design files the docs hand to users (``docs/designs``, ``docs/answers``) are designs
    ``fingertip simulate`` reads, with the catalogue's materials."""
    from sim.design import load_design

    design = load_design(path)
    assert len(design.layers) >= 1
