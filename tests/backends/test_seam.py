"""The backend seam holds: outside rdgpu/backends/ no code switches on a backend's name or
reaches into its private members; every built-in backend implements the fused pass."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import rdgpu
from rdgpu.backends.base import Backend
from rdgpu.backends.registry import backend_names

ROOT = Path(rdgpu.__file__).resolve().parent
#: ``be.name == ...``, ``backend.name != ...``, ``be._private``, a backend module's private
SWITCH = re.compile(r"(\bbe|backend)\.name\s*(==|!=|\bin\b|\bnot in\b)"
                    r"|(\bbe|backend)\._[a-z]\w*"
                    r"|backends\.(\w+_backend|\w+_codegen|\w+_runtime) import _")


def test_no_code_outside_the_backends_looks_at_a_backend_s_name_or_privates():
    found = []
    for path in sorted(ROOT.rglob("*.py")):
        if "backends" in path.relative_to(ROOT).parts[:1]:
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if SWITCH.search(line):
                found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not found, "\n".join(found)


def test_the_built_ins_are_registered_and_implement_the_fused_pass():
    assert backend_names()[:3] == ("numpy", "warp", "opencl")
    from rdgpu.backends.numpy_backend import NumpyBackend

    assert NumpyBackend.fused_pass is not Backend.fused_pass
    for module, cls in (("rdgpu.backends.warp_backend", "WarpBackend"),
                        ("rdgpu.backends.opencl_backend", "OpenCLBackend")):
        found = getattr(pytest.importorskip(module), cls)
        assert found.fused_pass is not Backend.fused_pass


def test_the_cli_names_the_registered_backends(capsys):
    from rdgpu.cli.app import build_parser

    with pytest.raises(SystemExit):
        build_parser().parse_args(["run", "--help"])
    assert "numpy, warp, opencl or auto" in " ".join(capsys.readouterr().out.split())
