"""User-facing error type shared by every package.

A :class:`UserError` is raised for anything the user can fix (bad YAML, unknown vehicle, bad
numbers). The CLI prints its message on one line to stderr and exits with code 2, without a
traceback. Messages name the file, the key and the expected form where there is one.
"""

from __future__ import annotations


class UserError(Exception):
    """A mistake in user input; ``str(err)`` is the one-line message shown to the user."""


def where(source: str | None, key: str | None) -> str:
    """Return a ``"file: key: "`` prefix for error messages (parts omitted when unknown)."""
    parts = [p for p in (source, key) if p]
    return ": ".join(parts) + (": " if parts else "")
