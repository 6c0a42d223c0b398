"""The golden-output harness (tests/golden, docs/golden.md) itself: a recording checks
clean against an unchanged code base, and any change to a result (one ulp, its dtype, its
shape, a scalar output, a case that starts raising) is reported by case, backend and dtype.

No stored recording is compared against here: hashes are per machine (docs/golden.md)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from golden import Case, case_list, check, digest, record
from golden.__main__ import main

ROOT = Path(__file__).resolve().parent.parent
FEW = ("spmv", "laplacian 9-point periodic", "sor_solve", "model gray-scott euler")


def _few() -> list[Case]:
    cases, _ = case_list()
    few = [c for c in cases if c.name in FEW]
    assert {c.name for c in few} == set(FEW)
    return few


def test_record_then_check_is_clean(tmp_path):
    """Two runs of the same cases agree bit for bit, and no case raised."""
    path = tmp_path / "golden.json"
    doc = record(path, _few())
    assert not [k for k, v in doc["cases"].items() if v["hash"].startswith("error:")]
    assert json.loads(path.read_text())["cases"] == doc["cases"]
    assert check(path) == []  # reruns exactly the recorded cases
    sor = next(v for k, v in doc["cases"].items() if k.startswith("sor_solve"))
    assert set(sor["scalars"]) == {"residual", "sweeps"}  # scalar outputs kept exactly
    assert sor["scalars"]["sweeps"] > 0


def test_perturbed_result_is_reported(tmp_path):
    """A case whose result moves by one ulp is named with its backend and dtype, with the
    output that changed; the others stay clean."""
    path = tmp_path / "golden.json"
    few = [c for c in _few() if c.backend == "numpy"]
    record(path, few)
    target = next(c for c in few if c.name == "spmv" and c.dtype == "float32")

    def nudged(be, dt):
        out = dict(target.run(be, dt))
        y = np.array(out["y"])
        y[3] = np.nextafter(y[3], np.inf)
        return {**out, "y": y}

    changed = [Case(c.name, c.backend, c.dtype, nudged) if c is target else c for c in few]
    problems = check(path, changed)
    assert len(problems) == 1, problems
    assert problems[0].startswith("spmv [numpy, float32]: differs (y: ")


def test_digest_sees_bits_dtype_shape_and_scalars():
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    base = digest({"a": a, "n": 3, "r": 0.1})["hash"]
    assert digest({"a": a.copy(), "n": 3, "r": 0.1})["hash"] == base
    variants = [
        {"a": a.reshape(4, 3), "n": 3, "r": 0.1},                # shape
        {"a": a.view(np.int32), "n": 3, "r": 0.1},               # dtype, same bytes
        {"a": a, "n": 4, "r": 0.1},                              # an integer output
        {"a": a, "n": 3, "r": np.nextafter(0.1, 1.0)},           # a float, by one ulp
        {"b": a, "n": 3, "r": 0.1},                              # an output's name
    ]
    assert all(digest(v)["hash"] != base for v in variants)


def test_cli_exit_codes_and_a_case_that_starts_raising(tmp_path, capsys, monkeypatch):
    """``record`` then ``check`` exits 0; a recording another run disagrees with (here a
    case that raised) exits 1 and names it."""
    path = tmp_path / "g.json"
    assert main(["record", str(path), "--only", "spmv [numpy"]) == 0
    assert main(["check", str(path)]) == 0
    doc = json.loads(path.read_text())
    key = "spmv [numpy, float64]"
    doc["cases"][key] = {"hash": "error: ValueError: boom", "arrays": {}, "scalars": {}}
    path.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"{key}: differs (was 'error: ValueError: boom'" in out
    assert "spmv [numpy, float32]" not in out


def test_runs_as_a_module_from_the_repository_root():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.run([sys.executable, "-m", "tests.golden", "list", "--only", "spmv"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "spmv [numpy, float32]" in p.stdout


@pytest.mark.parametrize("kind", ["model", "dla", "random_walk_dla"])
def test_every_case_kind_is_listed_on_each_backend(kind):
    cases, notes = case_list()
    backends = {c.backend for c in cases}
    assert "numpy" in backends
    for be in backends:
        assert any(c.name.startswith(kind) and c.backend == be for c in cases), (kind, be)
