"""Where kernels run: the device-array layer and the `rdgpu.backends.base.Backend`
interface (``base.py``), the registry (``registry.py``: ``get_backend``, ``set_backend``,
``use_backend``, ``available_backends``, ``register_backend``), a domain bound to a backend
and the compiled fused pass of a Program (``target.py``: ``Target``, ``FusedPass``,
``HostFusedPass``), the interop hooks (``interop.py``), and the built-in backends: NumPy
(``numpy_backend.py``), Warp (``warp_backend.py`` with ``warp_runtime.py`` and the printer
``warp_codegen.py``) and OpenCL (``opencl_backend.py`` with ``opencl_devices.py`` and the
printer ``opencl_codegen.py``); the reductions' timing (``reduce_timing.py``,
``perf/reduce.py``).  The families that launch from their own folders
(``rdgpu/families/<family>/{numpy,warp,opencl}.py``: bernoulli, mesh, reduce, dla,
walkers) reach a backend through ``Backend.kernel`` and its public runtime methods.

A new backend subclasses ``Backend`` (memory, reductions, and ``fused_pass`` for models),
and registers a factory: ``register_backend("mine", Mine)``; then ``backend="mine"`` works
everywhere, ``Simulation`` and the CLI included (``tests/backends/test_outside_backend.py``).
"""
