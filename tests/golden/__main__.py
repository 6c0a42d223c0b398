"""``python -m tests.golden record OUT.json`` / ``check OUT.json`` (package doc)."""

from __future__ import annotations

import argparse
import sys

from .harness import case_list, check, record


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tests.golden", description=__doc__)
    p.add_argument("command", choices=("record", "check", "list"))
    p.add_argument("path", nargs="?", help="the recording (JSON)")
    p.add_argument("--only", action="append", metavar="TEXT",
                   help="record only the cases whose name contains TEXT (repeatable)")
    p.add_argument("-v", "--verbose", action="store_true", help="one line per case")
    a = p.parse_args(argv)
    log = (lambda s: print(s, flush=True)) if a.verbose else None
    if a.command == "list":
        cases, notes = case_list(a.only)
        for c in cases:
            print(c.key)
        for n in notes:
            print("note:", n)
        print(f"{len(cases)} cases")
        return 0
    if a.path is None:
        p.error(f"{a.command} needs the path of the recording")
    if a.command == "record":
        cases, notes = case_list(a.only)
        doc = record(a.path, cases, notes, log=log)
        errors = [k for k, v in doc["cases"].items() if v["hash"].startswith("error:")]
        for n in notes:
            print("note:", n)
        print(f"recorded {len(cases)} cases in {doc['seconds']:.1f} s to {a.path}"
              + (f" ({len(errors)} raised: {', '.join(errors)})" if errors else ""))
        return 0
    if a.only:
        p.error("--only is for record; check reruns the cases in the recording")
    problems = check(a.path, log=log)
    for line in problems:
        print(line)
    if problems:
        print(f"{sum(not x.startswith('note:') for x in problems)} case(s) differ")
        return 1
    print("every case bit-identical")
    return 0


if __name__ == "__main__":
    sys.exit(main())
