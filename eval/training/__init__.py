"""Training: one run from its configuration to its run directory.

`config` (RunConfig, the methods), `runner` (the training loop, `train`), `seed_run` (one seed's
state in a batch), `evaluate` (batched evaluation from p0 and ood starts), and the run directory's
files: `run_files` (their names, writers and readers), `atomic` (whole-file writes), `checksums`,
`provenance`, `tracking` (progress and live sinks) and `compress` (episode logs gzipped in place).
Nothing here imports `lava_bridge_mj.eval.sweeps` or `lava_bridge_mj.eval.analysis`."""
