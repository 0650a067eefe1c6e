"""User-facing errors, reading user files with one-line errors, and writing outputs atomically.

The bottom layer: every other package reports user mistakes as :class:`UserError` and reads and
writes files through these helpers.
"""

from proxplan.fileio.errors import UserError, where
from proxplan.fileio.files import (
    atomic_output,
    atomic_write_bytes,
    atomic_write_text,
    check_output_file,
    output_folder,
    parse_yaml,
    read_json,
    read_text,
    read_yaml,
    save_figure,
)

__all__ = [
    "UserError",
    "atomic_output",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_output_file",
    "output_folder",
    "parse_yaml",
    "read_json",
    "read_text",
    "read_yaml",
    "save_figure",
    "where",
]
