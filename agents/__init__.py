"""Agents: SAC, replay buffers, start-state strategies and baselines."""
