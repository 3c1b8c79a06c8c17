"""The command reference: every command and option, from the argparse parsers ``derive`` builds
(derive.cli.command_parsers)."""
from __future__ import annotations

import argparse

from derive.cli import COMMANDS, command_parsers

from gen import cell


def _flags(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest}`" + (" (optional)" if action.nargs in ("?", "*") else "")
    shown = ", ".join(f"`{s}`" for s in action.option_strings)
    if action.nargs == 0:
        return shown
    metavar = action.metavar or (("{" + ",".join(map(str, action.choices)) + "}") if action.choices
                                 else action.dest.upper())
    return f"{shown} `{metavar}`"




def _default(action: argparse.Action) -> str:
    if action.nargs == 0 or action.default in (None, argparse.SUPPRESS):
        return ""
    return f"`{action.default}`" if action.default != "" else '`""`'


def options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The parser's arguments as documented: every action but help."""
    return [a for a in parser._actions if not isinstance(a, argparse._HelpAction)]


def page() -> str:
    """The Markdown of docs/reference/commands.md."""
    top, commands = command_parsers()
    lines = ["# Commands", "",
             "Generated at build time from the argparse parsers `derive` builds "
             "(`derive.cli.command_parsers`): every command and every option, with its default. "
             "`derive COMMAND --help` prints the same.", "",
             "```text", top.format_usage().strip(), "```", "",
             "| command | what |", "| --- | --- |"]
    lines += [f"| [`{name}`](#derive-{name}) | {cell(help_text)} |" for name, (_, help_text) in COMMANDS.items()]
    lines += ["", "Top-level option: " + ", ".join(_flags(a) + f": {cell(a.help)}" for a in options(top)
                                                   if not isinstance(a, argparse._SubParsersAction)) + ".", ""]
    for name, parser in commands.items():
        lines += [f"## derive {name}", "", cell(COMMANDS[name][1]).capitalize() + ".", "",
                  "```text", parser.format_usage().strip(), "```", "",
                  "| argument | default | meaning |", "| --- | --- | --- |"]
        lines += [f"| {_flags(a)} | {_default(a)} | {cell(a.help)} |" for a in options(parser)]
        lines.append("")
    return "\n".join(lines)
