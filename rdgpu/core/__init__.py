"""The bottom layer: errors, the floating-point environment (subnormals flushed),
argument checks, the memory estimate, atomic files, optional extras, CSR and NPZ checks.
Imports nothing else of rdgpu."""
