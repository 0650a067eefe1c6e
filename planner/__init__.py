"""Scenario loading, multi-vehicle planning (OMPL, CasADi, Ruckig) and plan verification."""
