"""The ``rdgpu`` command."""

from rdgpu.cli.app import main

__all__ = ["main"]
