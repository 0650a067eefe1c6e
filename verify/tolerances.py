"""Tolerances and thresholds of the verifier (one home: the checks and the swarm planner's tracks
read them from here)."""

GOAL_TOLERANCE_M = 0.05  # goal, hover, dock and start positions, m
USAGE_TOLERANCE = 1e-3  # authority usage, -
KINEMATIC_TOLERANCE = 1.02  # 2 % on speed / acceleration; jerk from finite differences gets 10 %
JERK_TOLERANCE = 1.1
POSITION_CONSISTENCY_M = 2e-3  # position vs integrated velocity/acceleration per step, m
VELOCITY_CONSISTENCY_MPS = 5e-3  # velocity vs integrated acceleration per step, m/s
REST_SPEED_MPS = 0.05  # "at rest" (end of the plan; no tracking tube while both of a pair rest), m/s
