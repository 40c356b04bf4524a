"""Running a line: the launcher that starts a run's nodes, the node factory that forks them, the hosts they run on."""
