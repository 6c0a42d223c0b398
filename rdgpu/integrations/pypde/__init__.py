"""rdgpu as a py-pde backend: translation of a py-pde PDE into a model, the steppers."""
