"""Disturbance model, controller authority and precomputed cost maps (no planner imports here)."""
