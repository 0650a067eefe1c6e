"""``python -m proxplan ...``: the same command line as the ``proxplan`` script (:func:`proxplan.cli.main`)."""

from __future__ import annotations

import sys

from proxplan.cli import main

if __name__ == "__main__":
    sys.exit(main())
