"""The walkers kernel family: random-walker DLA (seed 001 §2, driven by
:mod:`rdgpu.growth.walkers`): Philox-4x32-10 keyed by (seed, walker, step), written out
once per language and shared with the noise family (``rdgpu/families/philox.py``,
``warp_philox.py``, ``philox.cl``), ``walker_steps`` (each step moves every walker once,
one thread per walker, then adds the cells of those that stick in walker id order, one
thread) and ``philox`` (the raw random stream, for tests).  Every backend grows the same
cluster (the conventions are in ``reference.py``).

``reference.py`` (NumPy), ``warp_kernels.py`` + ``warp.py`` (Warp kernels and their
launchers), ``walkers.cl`` + ``opencl.py`` (OpenCL C, integer only and built as a program
of its own after the header ``philox.cl``, without ``common.cl``, and its launchers),
``numpy.py`` (the reference as the NumPy backend's launchers).  The arrays are the
driver's own (it builds them with the dtypes and shapes of ``Backend.walker_steps``), so
the launchers take them unchecked.
"""
