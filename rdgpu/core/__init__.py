"""The bottom layer: errors, the floating-point environment (subnormals flushed), the
shared conventions (real dtypes, axis names), argument checks, the memory estimate, the
CPU's caches, atomic files, optional extras, CSR and NPZ checks.
Imports nothing else of rdgpu."""
