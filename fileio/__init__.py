"""User-facing errors, reading user files with one-line errors, declared file formats, and writing
outputs atomically.

The bottom layer: every other package reports user mistakes as :class:`UserError`, reads and
writes files through these helpers, and declares its file formats on :class:`FileModel` (pydantic)
with the shared value types (:data:`Number`, :data:`Positive`, :data:`Vec3`, ...), validating each
parsed document once with :func:`validate` (one-line errors with key path, expected form and a
did-you-mean for unknown keys) and publishing it with :func:`json_schema`. The declared-format names
load pydantic on first use (module ``__getattr__``), so ``proxplan --help`` stays fast.
"""

from typing import TYPE_CHECKING, Any

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

if TYPE_CHECKING:
    from proxplan.fileio.models import (
        FileModel,
        Flag,
        Name,
        NonNegative,
        Number,
        Positive,
        Text,
        Vec3,
        Whole,
        expected_form,
        json_schema,
        missing,
        optional,
        problem,
        schema_rows,
        validate,
    )

__all__ = [
    "FileModel",
    "Flag",
    "Name",
    "NonNegative",
    "Number",
    "Positive",
    "Text",
    "Vec3",
    "Whole",
    "expected_form",
    "json_schema",
    "missing",
    "optional",
    "problem",
    "schema_rows",
    "validate",
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


def __getattr__(name: str) -> Any:
    if name in __all__:  # a declared-format name (the others are bound above)
        from proxplan.fileio import models

        return getattr(models, name)
    raise AttributeError(f"module 'proxplan.fileio' has no attribute {name!r}")
