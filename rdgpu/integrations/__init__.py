"""rdgpu inside other tools (py-pde)."""
