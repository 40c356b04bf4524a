"""Tools that try a robot against the physics: seeded pick trials, drive-gain tuning, a robot model's check."""
