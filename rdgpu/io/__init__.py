"""Files out and in: :mod:`~rdgpu.io.output` (PNG, movies, mesh files, ``write_outputs``;
the public ``rdgpu.output``), :mod:`~rdgpu.io.rendering` (off-screen pyvista renders),
:mod:`~rdgpu.io.volumes` (3-D grid pictures), :mod:`~rdgpu.io.images` (colour maps),
:mod:`~rdgpu.io.datafile` (NPZ data files) and :mod:`~rdgpu.io.writers` (shared rules)."""
