#!/usr/bin/env bash
# The GPU checks of rdgpu: the suite's cross-checks against the NumPy reference on GPU OpenCL
# and on Warp CUDA, and the GPU rows of `rdgpu bench --rows ...` (warp-cuda, opencl-gpu).
#
# Run from the repository root on a machine with an NVIDIA GPU, with pyopencl (stage opencl)
# and warp-lang (stage warp) importable by $PYTHON (default python3), and trimesh (the mesh
# tests: without it ~150 tests per backend fail in SurfaceMesh.icosphere/torus):
#
#     OUT=/tmp/gpu perf/gpu_check.sh info opencl warp bench bench2
#
# Stages, each time-boxed (STEP_S seconds per pytest run, BENCH_S for the benchmark):
#   info    nvidia-smi and the Python packages
#   opencl  the test files below on the first OpenCL GPU (numpy- and warp-only tests left
#           out; RDGPU_OPENCL_DEVICE picks another), junit XML in $OUT/junit-opencl.xml
#   warp    the same on Warp's cuda:0 (RDGPU_TEST_WARP_DEVICE, see tests/conftest.py),
#           numpy- and opencl-only tests left out, $OUT/junit-warp.xml
#   bench   rdgpu bench --rows kernels, GPU backends only, grid kernels at 1024², 4096²,
#           8192² (beyond an H100's 50 MB or H200's 60 MB L2), bench.md/json and
#           bench-kernels.png in $OUT
#   bench2  its mesh, model, ensemble and growth rows, in $OUT/bench2
# First run (2026-11-27, H200): wheels carried to a machine without a package index (warp-lang
# 1.19.0 repacked as tar.xz without examples/tests, 99 MB, in two calls), pytest-xdist there.
# NVIDIA's OpenCL driver mounted into a container often comes without an ICD file: unless
# OCL_ICD_VENDORS is set, one naming the libnvidia-opencl found is written in /tmp and
# OCL_ICD_VENDORS set to it.
set -uo pipefail
OUT=${OUT:-perf/results/gpu}
PY=${PYTHON:-python3}
STEP_S=${STEP_S:-150}
BENCH_S=${BENCH_S:-150}
export PYTHONUNBUFFERED=1 PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$PWD
mkdir -p "$OUT"
FILES=${FILES:-"crosscheck/test_crosscheck crosscheck/test_mesh_kernels models/test_generated_kernels
  models/test_ensembles simulation/test_sim_3d crosscheck/test_reduce crosscheck/test_metric_kernels
  models/test_temporal_blocking crosscheck/test_levelset_3d crosscheck/test_one_d growth/test_walkers
  growth/test_dla core/test_subnormals backends/test_warp_backend_smoke backends/test_opencl_backend_smoke"}
paths() { for f in $FILES; do printf 'tests/%s.py ' "$f"; done; }
# a pytest plugin leaving out the tests parametrized with a backend named in $DROP_BACKENDS
# ("-k 'not numpy'" would also drop test_generated_kernels_equal_numpy[...-opencl-...])
mkdir -p /tmp/rdgpu_check && cat > /tmp/rdgpu_check/rdgpu_drop.py <<'PY'
import os

DROP = set(os.environ.get("DROP_BACKENDS", "").split())


def pytest_collection_modifyitems(config, items):
    keep, drop = [], []
    for item in items:
        spec = getattr(item, "callspec", None)
        values = {str(v) for v in spec.params.values()} if spec else set()
        (drop if values & DROP else keep).append(item)
    items[:] = keep
    config.hook.pytest_deselected(items=drop)
PY
export PYTHONPATH=$PYTHONPATH:/tmp/rdgpu_check PYTEST_PLUGINS=rdgpu_drop
# pytest-xdist where there is one (WORKERS processes); SIGINT at the time limit, so pytest
# stops cleanly and still writes its summary and junit XML
XDIST=""
$PY -c 'import xdist' 2>/dev/null && XDIST="-n ${WORKERS:-8}"
run_tests() {  # run_tests NAME DROP_BACKENDS
    DROP_BACKENDS=$2 timeout -s INT -k 20 "$STEP_S" $PY -m pytest -q -p no:cacheprovider \
        $XDIST --tb=short --junitxml "$OUT/junit-$1.xml" -o junit_family=xunit1 $(paths) 2>&1
}

opencl_icd() {
    [ -n "${OCL_ICD_VENDORS:-}" ] && return
    local lib
    lib=$(find /usr/local/nvidia /usr/lib /usr/lib64 /usr/lib/x86_64-linux-gnu \
          -name 'libnvidia-opencl.so*' 2>/dev/null | sort | head -1)
    if [ -z "$lib" ]; then echo "no libnvidia-opencl here: no NVIDIA OpenCL"; return; fi
    mkdir -p /tmp/icd && echo "$lib" > /tmp/icd/nvidia.icd
    export OCL_ICD_VENDORS=/tmp/icd
    echo "OpenCL ICD: $lib"
}

opencl_icd

for stage in "$@"; do
    echo "=== $stage $(date -u +%T)"
    case $stage in
    info)
        nvidia-smi
        nvidia-smi --query-gpu=name,memory.total,clocks.max.memory,driver_version --format=csv
        $PY -c 'import sys, numpy; print(sys.version, "numpy", numpy.__version__)'
        $PY -c 'import pyopencl as cl; print([(p.name, [d.name for d in p.get_devices()])
                for p in cl.get_platforms()])' 2>&1 | tail -2
        $PY -c 'import warp as wp; wp.init(); print("warp", wp.__version__,
                [d.alias for d in wp.get_devices()])' 2>&1 | tail -2
        ;;
    opencl)
        run_tests opencl "numpy warp warp-cells"
        ;;
    warp)
        RDGPU_TEST_WARP_DEVICE=${RDGPU_TEST_WARP_DEVICE:-cuda:0} \
            run_tests warp "numpy opencl opencl-strided"
        ;;
    bench)
        timeout "$BENCH_S" $PY -m rdgpu.cli bench --rows kernels --no-numpy \
            --backends warp-cuda opencl-gpu --sizes 1024 4096 8192 --seconds 0.3 --out "$OUT"
        ;;
    bench2)
        timeout "$BENCH_S" $PY -m rdgpu.cli bench --rows mesh models ensembles growth \
            --no-numpy --backends warp-cuda opencl-gpu --sizes 4096 --mesh-vertices 1000000 \
            --model-size 4096 --members 1024 --dla-sizes 512 --seconds 0.2 --out "$OUT/bench2"
        ;;
    *) echo "unknown stage $stage (info, opencl, warp, bench, bench2)"; exit 2 ;;
    esac
done
