"""Files out and in: `output` (PNG, movies, mesh files, ``write_outputs``;
the public ``rdgpu.output``), `rendering` (off-screen pyvista renders),
`volumes` (3-D grid pictures), `images` (colour maps),
`datafile` (NPZ data files) and `writers` (shared rules)."""
