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


def add_model_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--model MODEL.yaml``: a calibrated model file (``proxplan identify --save-model``)."""
    parser.add_argument(
        "--model",
        metavar="MODEL.yaml",
        help=f"calibrated model file (identify --save-model; proxplan.physics.model_file): {what}",
    )


def load_model_argument(args: argparse.Namespace, command: str):
    """The :class:`proxplan.physics.CalibratedModel` of ``--model`` (None without it); its notes go to stderr."""
    if not getattr(args, "model", None):
        return None
    import sys

    from proxplan.physics import load_model_file

    model = load_model_file(args.model)
    for note in model.notes:
        print(f"proxplan {command}: note: {note}", file=sys.stderr)
    return model
