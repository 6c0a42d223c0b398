"""Golden outputs: hashes of rdgpu's results through its public API, recorded before a
restructuring step and checked after it (issue 20: "every result must not change").

``python -m tests.golden record OUT.json`` runs every case (:mod:`.cases`) on every
available backend in both dtypes and writes one sha256 per case (over the output arrays'
names, dtypes, shapes and bytes, and the exact scalar outputs); ``python -m tests.golden
check OUT.json`` reruns them and reports each case whose hash differs, exiting 1.

The hashes are this machine's: a different CPU (AVX2 against AVX-512 code generation in
Warp/PoCL) or a different NumPy/Warp/PoCL may change the last bits, so a recording is
compared only on the machine, and with the packages, that made it (docs/golden.md).
Nothing in the test suite compares against a stored recording.
"""

from .harness import Case, case_list, check, digest, record, run_case

__all__ = ["Case", "case_list", "check", "digest", "record", "run_case"]
