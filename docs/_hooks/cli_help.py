"""MkDocs hook: a page line ``<!-- rdgpu-help: run -->`` becomes the ``--help`` text of
``rdgpu run`` (no argument: of ``rdgpu`` itself), taken from the CLI's own parser, so the
reference never falls behind the options."""

from __future__ import annotations

import argparse
import os
import re

MARKER = re.compile(r"^<!-- rdgpu-help:\s*([\w-]*)\s*-->$", re.M)


def _help(command: str) -> str:
    from rdgpu.cli.app import build_parser

    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: a fixed width
    parser = build_parser()
    if command:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[command]
    return parser.format_help()


def on_page_markdown(markdown: str, **kwargs) -> str:
    return MARKER.sub(lambda m: "```text\n" + _help(m.group(1)).rstrip() + "\n```", markdown)
