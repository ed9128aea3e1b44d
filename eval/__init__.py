"""Training runner, benchmark CLI, metrics, plots and rollout videos."""
