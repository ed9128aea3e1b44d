"""Package data: the generated MJCF model and the shipped demonstration sets."""
