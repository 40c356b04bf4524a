"""The running system: physics world, bus, nodes, CLI. Importing `fleet` imports no simulator."""
