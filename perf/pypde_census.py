"""Census: how many of py-pde's own example scripts run through rdgpu's py-pde backend.

Usage::

    python perf/pypde_census.py FOLDER [--backend rdgpu:numpy] [--timeout 120]
                                       [--out results.md]

Every ``*.py`` under ``FOLDER`` (recursively, sorted) runs in a fresh subprocess (a crash or
a hang stays isolated; ``--timeout`` seconds per script), with ``MPLBACKEND=Agg`` and a
fresh temporary working directory (the scripts write files).  The subprocess is this file
again (``--child``): it imports ``rdgpu.pypde`` and redirects py-pde's backend choice
before running the script with ``runpy.run_path(path, run_name="__main__")``:

* ``SolverBase._select_backend`` (every py-pde solver picks its backend there, for
  ``eq.solve(...)``, ``Controller`` and solvers built by hand) replaces a backend that is
  not rdgpu's (``"auto"``, ``"numba"``, ``"numpy"``, ... or a backend object) with
  ``--backend``;
* ``RdgpuBackend.make_stepper`` and ``RdgpuBackend.make_pde_rhs`` are wrapped so that
  the functions they return count their calls: a script counts as running on rdgpu only if
  rdgpu actually stepped (or evaluated a right-hand side for ``ScipySolver``).

The scripts are not edited and their settings are not lowered; one that runs past the
timeout is reported as ``timeout``.  Classes:

* ``runs on rdgpu``: the script finished and rdgpu stepped it;
* ``refused by rdgpu: <reason>``: ``rdgpu.pypde.UnsupportedPDE`` was raised;
* ``no PDE solved``: the script finished without any step on rdgpu;
* ``fails in rdgpu: <type>: <message>``: another exception raised inside rdgpu's code;
* ``fails: <type>: <message>``: any other exception (or the interpreter crashed);
* ``timeout``.

It prints a table and the totals per class and, with ``--out``, writes them as markdown.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path
from typing import Any

#: the prefix of every `UnsupportedPDE` message (left out of the table: it says nothing)
_REFUSAL_PREFIX = "py-pde backend 'rdgpu' cannot run this: "
#: the class names, in the order of the totals
CLASSES = ("runs on rdgpu", "refused by rdgpu", "no PDE solved", "fails in rdgpu", "fails",
           "timeout")


# ------------------------------------------------------------------------------ the child
def _counting(fn: Any, counters: dict[str, int], key: str) -> Any:
    """``fn`` counting its calls in ``counters[key]``."""

    def wrapped(*args: Any, **kwargs: Any) -> Any:
        counters[key] += 1
        return fn(*args, **kwargs)

    return wrapped


def install_redirect(target: str) -> dict[str, int]:
    """Make every py-pde solver run on the rdgpu backend ``target`` and return the counters
    of what rdgpu was asked to do (filled in while the script runs)."""
    from pde.backends import get_backend
    from pde.solvers.base import SolverBase

    import rdgpu.pypde

    backend_cls = rdgpu.pypde.RdgpuBackend
    get_backend(target)  # fails here, before any script, on a backend name rdgpu lacks
    counters = {"make_stepper": 0, "make_pde_rhs": 0, "stepper_calls": 0, "rhs_calls": 0,
                "redirected": 0}

    select = SolverBase._select_backend

    def select_rdgpu(self: Any, state: Any, **kwargs: Any) -> Any:
        current = self._backend
        is_rdgpu = isinstance(current, backend_cls) or (
            isinstance(current, str) and current.split(":")[0] == "rdgpu")
        if not is_rdgpu:
            counters["redirected"] += 1
            self._backend = target
        return select(self, state, **kwargs)

    SolverBase._select_backend = select_rdgpu

    make_stepper = backend_cls.make_stepper
    make_pde_rhs = backend_cls.make_pde_rhs

    def counted_stepper(self: Any, solver: Any, state: Any) -> Any:
        counters["make_stepper"] += 1
        return _counting(make_stepper(self, solver, state), counters, "stepper_calls")

    def counted_rhs(self: Any, eq: Any, state: Any) -> Any:
        counters["make_pde_rhs"] += 1
        return _counting(make_pde_rhs(self, eq, state), counters, "rhs_calls")

    backend_cls.make_stepper = counted_stepper
    backend_cls.make_pde_rhs = counted_rhs
    return counters


def _chain(err: BaseException) -> list[BaseException]:
    """``err`` and the exceptions it was raised from or while handling."""
    out: list[BaseException] = []
    while err is not None and err not in out:
        out.append(err)
        err = err.__cause__ or err.__context__
    return out


def describe_error(err: BaseException) -> dict[str, Any]:
    """What the parent needs of an exception: its type, first message line, whether it is
    (or came from) an `UnsupportedPDE` and whether it was raised inside rdgpu's code."""
    from rdgpu.pypde import UnsupportedPDE

    rdgpu_dir = str(Path(sys.modules["rdgpu"].__file__).resolve().parent)
    refusal = next((e for e in _chain(err) if isinstance(e, UnsupportedPDE)), None)
    shown = refusal or err
    frames = traceback.extract_tb(err.__traceback__)
    inside = any(str(Path(f.filename).resolve()).startswith(rdgpu_dir) for f in frames)
    lines = str(shown).strip().splitlines()
    return {"type": type(shown).__name__, "message": lines[0] if lines else "",
            "refused": refusal is not None, "in_rdgpu": inside,
            "where": f"{frames[-1].filename}:{frames[-1].lineno}" if frames else ""}


def run_child(script: str, target: str, result_path: str) -> int:
    """Run ``script`` with every solve on ``target``; write the outcome as JSON."""
    import runpy

    record: dict[str, Any] = {"error": None, "counters": {}}
    start = time.perf_counter()

    def on_timeout(signum: int, frame: Any) -> None:  # the parent's SIGTERM at the timeout
        Path(result_path).write_text(json.dumps({"timeout": True,
                                                 "counters": record["counters"]}))
        os._exit(0)

    signal.signal(signal.SIGTERM, on_timeout)
    try:
        record["counters"] = install_redirect(target)
        sys.argv = [script]
        sys.path.insert(0, str(Path(script).parent))
        runpy.run_path(script, run_name="__main__")
    except SystemExit as err:
        if err.code not in (None, 0):
            record["error"] = {"type": "SystemExit", "message": str(err.code),
                               "refused": False, "in_rdgpu": False, "where": ""}
    except BaseException as err:  # noqa: BLE001 - any failure of the script is a result
        record["error"] = describe_error(err)
    record["seconds"] = time.perf_counter() - start
    Path(result_path).write_text(json.dumps(record))
    return 0


# ----------------------------------------------------------------------------- the parent
def _last_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1].strip() if lines else ""


def _stop(proc: subprocess.Popen, sig: int) -> None:
    """Send ``sig`` to the process group of ``proc`` (a session this census started)."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass  # all of it has exited


def run_script(script: Path, backend: str, timeout: float) -> dict[str, Any]:
    """Run one example in a subprocess; the child's record plus ``timeout``/``crash``."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    with tempfile.TemporaryDirectory(prefix="pypde-census-") as work:
        result_path = Path(work) / "_census_result.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(script),
               "--backend", backend, "--result", str(result_path)]
        log = Path(work) / "_census_output.txt"
        start = time.perf_counter()
        with open(log, "wb") as out:
            proc = subprocess.Popen(cmd, cwd=work, env=env, stdout=out,
                                    stderr=subprocess.STDOUT, start_new_session=True)
            try:
                code = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                code = None
                _stop(proc, signal.SIGTERM)  # the child writes its counters and exits
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    pass
            _stop(proc, signal.SIGKILL)  # the child and whatever it started and left
            proc.wait()
        elapsed = time.perf_counter() - start
        output = log.read_text(errors="replace")
        if code is None:
            counters = {}
            if result_path.exists():
                counters = json.loads(result_path.read_text()).get("counters", {})
            return {"timeout": True, "seconds": elapsed, "counters": counters}
        if not result_path.exists():
            last = _last_line(output)
            return {"crash": f"exit code {code}" + f": {last}" * bool(last),
                    "seconds": elapsed, "counters": {}}
        record = json.loads(result_path.read_text())
    record["seconds"] = elapsed
    return record


def classify(record: dict[str, Any]) -> tuple[str, str]:
    """``(class, reason)`` of one script's record (the classes of `CLASSES`)."""
    counters = record.get("counters", {})
    stepped = counters.get("stepper_calls", 0) + counters.get("rhs_calls", 0) > 0
    if record.get("timeout"):
        return "timeout", "while stepping on rdgpu" if stepped else ""
    if "crash" in record:
        return "fails", f"crashed ({record['crash']})"
    err = record.get("error")
    if err is None:
        return ("runs on rdgpu", "") if stepped else ("no PDE solved", "")
    message = err["message"]
    if err["refused"]:
        return "refused by rdgpu", message.removeprefix(_REFUSAL_PREFIX)
    reason = f"{err['type']}: {message}" if message else err["type"]
    if not stepped:
        reason += " (before any rdgpu step)"
    return ("fails in rdgpu" if err["in_rdgpu"] else "fails"), reason


def label(cls: str, reason: str) -> str:
    """The class as the table shows it: ``"refused by rdgpu: <reason>"``."""
    return f"{cls}: {reason}" if reason else cls


def rdgpu_use(counters: dict[str, int]) -> str:
    """``"S+R / N"``: steppers and right-hand sides asked of rdgpu, and the calls into
    those it made."""
    if not counters:
        return ""
    calls = counters.get("stepper_calls", 0) + counters.get("rhs_calls", 0)
    return (f"{counters.get('make_stepper', 0)}+{counters.get('make_pde_rhs', 0)} / "
            f"{calls}")


def render(rows: list[dict[str, Any]], backend: str, folder: Path) -> str:
    """The markdown table and totals of ``rows`` (`census`'s)."""
    totals = Counter(row["class"] for row in rows)
    lines = [f"# py-pde examples on `{backend}`", "",
             f"{len(rows)} scripts under `{folder}`. *rdgpu*: steppers + right-hand sides "
             "asked of rdgpu / calls into those it made.", "",
             "| script | result | rdgpu | seconds |", "| --- | --- | --- | ---: |"]
    for row in rows:
        result = label(row["class"], row["reason"]).replace("|", "/")
        lines.append(f"| `{row['script']}` | {result} | {row['rdgpu']} | "
                     f"{row['seconds']:.1f} |")
    lines += ["", "| class | scripts |", "| --- | ---: |"]
    lines += [f"| {cls} | {totals[cls]} |" for cls in CLASSES if totals[cls]]
    lines.append(f"| total | {len(rows)} |")
    return "\n".join(lines) + "\n"


def census(folder: Path, backend: str, timeout: float) -> list[dict[str, Any]]:
    """Run every example under ``folder``, one at a time, printing each result; one row
    (``script``, ``class``, ``reason``, ``rdgpu``, ``seconds``) per script."""
    scripts = sorted(p for p in folder.rglob("*.py") if p.is_file())
    if not scripts:
        raise SystemExit(f"no *.py under {folder}")
    rows = []
    width = max(len(str(p.relative_to(folder))) for p in scripts)
    for i, script in enumerate(scripts, 1):
        name = str(script.relative_to(folder))
        record = run_script(script.resolve(), backend, timeout)
        cls, reason = classify(record)
        use = rdgpu_use(record.get("counters", {}))
        rows.append({"script": name, "class": cls, "reason": reason, "rdgpu": use,
                     "seconds": record["seconds"]})
        print(f"[{i:2d}/{len(scripts)}] {name:<{width}} {record['seconds']:6.1f}s "
              f"{use:>9}  {label(cls, reason)}", flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", type=Path,
                        help="folder with py-pde's example scripts (searched recursively)")
    parser.add_argument("--backend", default="rdgpu:numpy",
                        help="rdgpu backend every solve runs on (default rdgpu:numpy)")
    parser.add_argument("--timeout", type=float, default=120.0,
                        help="seconds allowed per script (default 120)")
    parser.add_argument("--out", type=Path, help="also write the table as markdown here")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--result", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return run_child(args.child, args.backend, args.result)
    if args.folder is None or not args.folder.is_dir():
        parser.error("FOLDER must be a directory")
    start = time.perf_counter()
    rows = census(args.folder, args.backend, args.timeout)
    text = render(rows, args.backend, args.folder)
    totals = Counter(row["class"] for row in rows)
    print()
    for cls in CLASSES:
        print(f"{cls:>18}: {totals[cls]}")
    print(f"{'total':>18}: {len(rows)}  ({time.perf_counter() - start:.0f} s)")
    if args.out:
        args.out.write_text(text)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
