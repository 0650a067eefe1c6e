"""Cost maps of a vehicle pair, built from the physics model: the cutoff map r_cut(dz) at several
authority levels and the 3-D wrench table with a smooth (numpy and CasADi) interpolant, stored as
.npz with a parameter hash; shipped maps for the built-in types in ``costmaps/data``.
"""

from proxplan.costmaps.cutoff import DEFAULT_LEVELS, INVALID_RULES, CutoffMap, build_cutoff_map, r_cut_from_usage
from proxplan.costmaps.effects import (
    AXIS_BREAKING_EFFECTS,
    effects_key,
    effects_of_key,
    map_effects,
    pair_wrench,
    sources_wrench,
    unmapped_effect_names,
)
from proxplan.costmaps.map_plot import plot_cutoff
from proxplan.costmaps.map_store import (
    DATA_DIR,
    FORMAT_VERSION,
    PairMaps,
    build_pair_maps,
    load_pair_maps,
    pair_maps,
    param_hash,
    save_pair_maps,
    shipped_path,
)
from proxplan.costmaps.wrench_table import WrenchTable, build_wrench_table

__all__ = [
    "AXIS_BREAKING_EFFECTS",
    "DATA_DIR",
    "DEFAULT_LEVELS",
    "FORMAT_VERSION",
    "INVALID_RULES",
    "CutoffMap",
    "PairMaps",
    "WrenchTable",
    "build_cutoff_map",
    "build_pair_maps",
    "build_wrench_table",
    "effects_key",
    "effects_of_key",
    "load_pair_maps",
    "map_effects",
    "pair_maps",
    "pair_wrench",
    "param_hash",
    "plot_cutoff",
    "r_cut_from_usage",
    "save_pair_maps",
    "shipped_path",
    "sources_wrench",
    "unmapped_effect_names",
]
