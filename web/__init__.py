"""Viser review app for scenarios and plans."""
