"""Firmware log variables (uSD events, LogDataGeneric topics) -> :class:`VehicleLog` through the contract.

Variables may sit in several events / topics at different rates: the clock is the one holding the
most contract variables, and the others are interpolated onto it linearly (each in its own time).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.formats.contract import CONTRACT, missing_variables, variable_table, vehicle_log
from proxplan.identify.vehicle_log import VehicleLog


def log_from_streams(
    streams: Sequence[tuple[np.ndarray, Mapping[str, np.ndarray]]],
    *,
    source: str,
    overrides: Mapping[str, str] | None = None,
    what: str = "variable",
) -> VehicleLog:
    """``streams``: (timestamps (N,) s, {log name: values (N,)}) each (an event, a topic). UserError
    naming ``source`` and each missing contract entry."""
    table = variable_table(overrides, source)
    available = {name for _, values in streams for name in values}
    missing = missing_variables(available, table)
    if missing:
        raise UserError(f"{source}: missing {what}(s) {', '.join(missing)} (contract name (log name); "
                        "a manifest's 'variables:' maps other names)")  # fmt: skip
    held = [sum(table[k] in values for k in CONTRACT) for _, values in streams]
    t_main = np.asarray(streams[int(np.argmax(held))][0], dtype=float)
    if t_main.size < 2:
        raise UserError(f"{source}: fewer than 2 samples")
    columns = {}
    for key in CONTRACT:
        for t, values in streams:
            if table[key] in values:
                v = np.asarray(values[table[key]], dtype=float)
                columns[key] = (
                    v if t is streams[int(np.argmax(held))][0] else np.interp(t_main, t, v, left=np.nan, right=np.nan)
                )
                break
    return vehicle_log(t_main, columns, source=source)
