"""Sweeps: many training runs at once and their compact copies.

`sweep` (the grid and its command), `sweep_jobs` (one job per run, run in a subprocess or locally),
`sweep_ray` (the same jobs on a Ray cluster) and `export` (finished runs copied to results/).
Built on `lava_bridge_mj.eval.training`."""
