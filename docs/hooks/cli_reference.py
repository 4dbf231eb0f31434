"""The CLI reference page, generated from the ``jaxsimrl`` argparse parsers at every docs build.

mkdocs calls :func:`on_page_markdown` (``hooks:`` in mkdocs.yml) for each page; on ``cli.md`` it
replaces the :data:`MARKER` line with :func:`cli_reference`, one section per subcommand: its summary,
description, usage and a table of its arguments, all read from the parsers that ``jaxsimrl`` itself
builds (``jaxsimrl.cli.main.build_parser``).

Why a build-time hook and not a committed, generated page: the help texts change with the code (a new
flag, a new subcommand registered in ``SUBCOMMAND_MODULES``), and a page generated at build time cannot
go stale, so there is no "regenerate the page" step to forget and no copy to review. The suite's strict
build (tests/test_docs.py) runs this hook, so a parser that cannot be documented fails the suite.
``python docs/hooks/cli_reference.py`` prints the generated markdown.

The formatter's ``_format_action_invocation``/``_expand_help`` are argparse's own (private, but stable
since Python 3.2): the page shows each argument exactly as ``--help`` does.
"""

from __future__ import annotations

import argparse
import re
from typing import Any

MARKER = "<!-- cli-reference -->"
PAGE = "cli.md"
#: A fixed width, so that the usage lines do not depend on the terminal the docs are built in.
WIDTH = 100


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """mkdocs event: fill the CLI reference page; every other page passes through unchanged."""
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise ValueError(f"docs/{PAGE} lost its {MARKER} line: the generated reference has nowhere to go")
    return markdown.replace(MARKER, cli_reference())


def cli_reference() -> str:
    """Markdown for every ``jaxsimrl`` subcommand, in the order ``jaxsimrl --help`` lists them."""
    from jaxsimrl.cli.main import build_parser

    parser = build_parser()
    commands = subcommands(parser)
    summaries = {choice.dest: choice.help or "" for choice in _subparsers_action(parser)._choices_actions}
    lines = ["```text", _usage(parser), "```", "", "| command | what it does |", "|---|---|"]
    lines += [f"| [`{name}`](#{slug(name)}) | {_cell(summaries.get(name, ''))} |" for name in commands]
    for name, sub in commands.items():
        lines += ["", *_command(name, sub, summaries.get(name, ""))]
    return "\n".join(lines) + "\n"


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The subcommand parsers of ``parser`` by name (aliases left out)."""
    action = _subparsers_action(parser)
    names = [choice.dest for choice in action._choices_actions]
    return {name: action.choices[name] for name in names}


def slug(name: str) -> str:
    """The anchor of a subcommand's heading (the heading is ``jaxsimrl NAME``, as toc slugifies it)."""
    return "jaxsimrl-" + re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")


def _subparsers_action(parser: argparse.ArgumentParser) -> Any:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    raise ValueError(f"{parser.prog} has no subcommands")


def _formatter(parser: argparse.ArgumentParser) -> argparse.HelpFormatter:
    return parser.formatter_class(prog=parser.prog, width=WIDTH)


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = _formatter(parser)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups, prefix="")
    return formatter.format_help().strip()


def _command(name: str, parser: argparse.ArgumentParser, summary: str) -> list[str]:
    """One subcommand's section: heading, summary, description, usage, argument table."""
    lines = [f"## jaxsimrl {name} {{#{slug(name)}}}", ""]
    if summary:
        lines += [_text(summary[:1].upper() + summary[1:]) + ".", ""]
    if parser.description:
        lines += [_text(parser.description), ""]
    lines += ["```text", _usage(parser), "```", "", "| argument | meaning |", "|---|---|"]
    formatter = _formatter(parser)
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
            continue
        invocation = formatter._format_action_invocation(action)
        meaning = formatter._expand_help(action) if action.help else ""
        if action.required and action.option_strings:
            meaning = f"(required) {meaning}"
        lines.append(f"| `{invocation}` | {_cell(meaning)} |")
    return lines


def _text(text: str) -> str:
    """Plain help text as markdown: argparse's wrapping undone, markdown's special characters escaped."""
    text = " ".join(text.split())
    text = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return re.sub(r"([\\`*_\[\]#|])", r"\\\1", text)


def _cell(text: str) -> str:
    return _text(text) or " "


if __name__ == "__main__":
    print(cli_reference())
