"""Snapshots of a whole lockstep run: every process's state at one tick boundary, in one file, and back."""
