"""What every part of the running system shares: starting and stopping OS processes, loading a scene with its robots."""
