"""Independent tasks fanned out on Dask (``dask.distributed``): a local cluster on this machine's
cores by default, or an existing cluster given by its scheduler address. The one place where work
leaves the calling process; certification, swarm planning and cost maps for many pairs use
:func:`fan_out` (one function over many items); ``proxplan identify`` runs independent stages beside
each other with :func:`background`.
"""

from proxplan.fanout.background import Background, Shared, Task, background
from proxplan.fanout.engine import FanoutResult, fan_out

__all__ = ["Background", "FanoutResult", "Shared", "Task", "background", "fan_out"]
