"""Closed-loop multirotor simulation with downwash (RotorPy) and synthetic flight logs."""
