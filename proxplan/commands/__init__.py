"""One module per command group; each exposes ``register(subparsers)`` and imports only argparse
at module level, so ``proxplan --help`` stays fast (heavy packages load inside the handlers)."""
