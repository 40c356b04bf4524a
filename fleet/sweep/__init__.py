"""Scenario sweeps: a grid of runs over seeds, allocators and scene overrides, on local cores or a Ray cluster."""
