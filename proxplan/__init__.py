"""Command-line entry point of proxplan (the `proxplan` console script)."""
