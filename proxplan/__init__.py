"""The ``proxplan`` command line: a thin dispatcher (:mod:`proxplan.cli`) over one module per
command group in :mod:`proxplan.commands`; the top layer, importing the packages below."""
