"""Every benchmark behind `fleet bench`: raw physics, the bus, whole lines, the guard and allocator, the env, the
monitor, recording."""
