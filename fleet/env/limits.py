"""The env's fixed numbers: the observation limit, the nearest-arm cap and the reward weights."""

OBS_LIMIT = 100.0  # joint velocities are clipped here; positions and angles never come near
SEPARATION_CAP_M = 0.2  # the nearest-arm distance an agent sees is capped here: farther arms need no FCL query
NEAR_MISS_PENALTY, CONTACT_PENALTY, LIMIT_PENALTY, EFFORT_WEIGHT, TEAM_WEIGHT = 0.5, 1.0, 0.1, 0.01, 0.1
