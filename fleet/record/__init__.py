"""Recording runs to MCAP (rosbag2 layout), reading them back, replaying them and reporting on them."""
