"""Independent tasks fanned out on Dask (``dask.distributed``): a local cluster on this machine's
cores by default, or an existing cluster given by its scheduler address. The one place where work
leaves the calling process; certification, swarm planning and cost maps for many pairs use it.
"""

from proxplan.fanout.engine import FanoutResult, fan_out

__all__ = ["FanoutResult", "fan_out"]
