"""Argument types and the parser class shared by every command (argparse only)."""

from __future__ import annotations

import argparse
from typing import NoReturn


class OneLineParser(argparse.ArgumentParser):
    """argparse with one-line errors (``proxplan CMD: error: ...``, exit 2) instead of usage dumps."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def seed_argument(text: str) -> int:
    """``--seed``: a whole number in [0, 2^31 - 1]."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, {2**31 - 1}], got {text!r}") from None
    if not 0 <= value <= 2**31 - 1:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, {2**31 - 1}], got {value}")
    return value
