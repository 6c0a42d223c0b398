"""Growth: fronts driven by reaction-diffusion (level sets), diffusion-limited aggregation
and random walkers."""
