"""Files out and in: pictures, movies, meshes, NPZ data files (:mod:`rdgpu.io.output`)."""
