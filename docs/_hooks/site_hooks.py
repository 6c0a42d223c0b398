"""MkDocs hooks: a page line ``<!-- rdgpu-help: run -->`` becomes the ``--help`` text of
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


#: a Sphinx role left in a docstring (``:func:`name```): mkdocstrings shows it verbatim
ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|exc|obj|py:\w+):<code>(~?)([^<]*)</code>")


def on_page_content(html: str, **kwargs) -> str:
    """Docstrings written with Sphinx roles render as plain code (``~a.b.c`` as ``c``)
    until each is converted to the numpydoc/Markdown convention (docs/architecture.md,
    Docstrings)."""
    return ROLE.sub(lambda m: "<code>" + (m.group(2).rsplit(".", 1)[-1] if m.group(1)
                                          else m.group(2)) + "</code>", html)
