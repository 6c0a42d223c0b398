"""``rdgpu bench``: rdgpu's backends and the peers a user would pick instead (numba,
py-pde, pystencils; Devito, Taichi named) on the same Gray-Scott step, each checked against
rdgpu's NumPy reference before it is timed, at grid sizes read off the machine's measured
cache, with the triad roofline; and, with ``--rows``, every kernel family, the mesh
kernels, the models, ensembles, temporal blocking, growth and real states (the
developers' benchmark).

* `rdgpu.bench.machine`: the triad sweep, the effective LLC, grid sizes, the machine record;
* `rdgpu.bench.problem`: the problem, its real state and its NumPy reference;
* `rdgpu.bench.contenders`: rdgpu's contenders and the check; `rdgpu.bench.peers`: the peers;
* `rdgpu.bench.run`: one run as a record; `rdgpu.bench.report`: JSON, Markdown, plots;
* `rdgpu.bench.groups`: the row groups of ``--rows`` beyond the peers, each in its module
  (`rdgpu.bench.rows_kernels`, `rows_mesh`, `rows_models`: models and ensembles,
  `rows_states`: real states and temporal blocking, `rows_growth`), given a
  `rdgpu.bench.context.Context`; `rdgpu.bench.devices`: backends by label (the GPUs),
  each device's memory, timing and the roofline.
"""
