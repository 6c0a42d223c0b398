"""Many runs: parameter sweeps as Dask tasks, and their store."""
