"""Closed-loop flights written as Neural-Swarm logs + a manifest, with effects beyond the model hidden in
the simulated air: what ``proxplan identify`` is checked on (tests/identify/test_identify.py, issue 35's
"each named library effect selected alone") and ``benchmarks/bench_library_alone.py``."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from proxplan.flightsim.logs import write_flight_logs
from proxplan.flightsim.scenarios_synthetic import swap_plan, takeoff_hover_plan
from proxplan.flightsim.simulate import simulate_plan
from proxplan.physics import Effect

SWAP_GAPS_M = (0.3, 0.6, 1.0, 0.4, 0.8, 0.35, 0.45)
"""Vertical gaps of the swaps, m: six train flights, then the test flight."""
SWAP_CENTRES_Z_M = (1.0, 1.4, 1.0, 0.7, 1.5, 1.2, 0.9)
"""Height of each swap's centre, m: the bottom vehicle's height not tied to the gap."""
TAKEOFF_LOW_Z_M = (0.06, 0.07, 0.08, 0.10, 0.11, 0.12, 0.09)
"""Start height of each take-off (the ground flights), m: the test flight starts 9 cm up."""
HIDDEN_EFFECTS = {
    "thrust_bias": Effect("thrust_bias", {"force_z_N": 0.06}),
    "ground_effect": Effect("ground_effect", {"gain_k": 2.5}),
    "near_field": Effect("near_field", {"amplitude": 1.5, "decay_L": 3.0}),
    "wake_swirl": Effect("wake_swirl", {"yaw_per_force_m": 0.05}),
    "wake_advection": Effect("wake_advection", {"wind_x_mps": 1.0, "wind_y_mps": 0.5, "convection_speed_mps": 2.0}),
    "own_velocity": Effect("own_velocity", {"c_w_spm": 0.12, "c_mu_spm": 0.05, "c_mu2_s2pm2": 0.08}),
    "thrust_quadratic": Effect("thrust_quadratic", {"b_q_rel_spm": 0.4}),
}
"""The named library effects, each at the strength the checks hide it at (force_z_N in N, wind in m/s, c_w and b_q
in s/m, c_mu2 in s^2/m^2, decay in units of the source's size L): one at a time in the simulated air of
:func:`simulated_swap_manifest` (tests/identify/test_identify.py, benchmarks/bench_library_alone.py)."""
SEED_STRIDE = 1000
"""Replicate r of a flight k is simulated with seed k + SEED_STRIDE r (noise and gusts drawn anew)."""


def simulated_swap_manifest(
    root: Path, effects: Sequence[Effect], *, type_name: str, ground: bool = False, replicate: int = 0
) -> Path:
    """Seven closed-loop RotorPy flights (:func:`proxplan.flightsim.simulate_plan`) with the hidden ``effects``,
    written under ``root`` as Neural-Swarm logs + manifest (:func:`proxplan.flightsim.write_flight_logs`); the
    manifest's path. Two ``type_name`` vehicles swapping places stacked :data:`SWAP_GAPS_M` apart (six train
    flights, one test), crossing 3 cm apart sideways (as real swaps do; an exact on-axis crossing leaves the
    roll torque with mocap noise only), at heights not tied to the gap (else an effect of the height above
    the floor is one of the gap); or (``ground``) take-off/hover sweeps near the ground. Selection holds whole
    flights out, so an effect must act in several train flights to be judged: a short-range one (near_field,
    decays within a few L) acts in the close ones. ``replicate``: the simulation's seeds (:data:`SEED_STRIDE`)."""
    manifest = root / "manifest.yaml"
    for k, gap_m in enumerate(SWAP_GAPS_M):
        split = "test" if k == len(SWAP_GAPS_M) - 1 else "train"
        if ground:
            plan = takeoff_hover_plan(type_name=type_name, low_z_m=TAKEOFF_LOW_Z_M[k], high_z_m=0.6, climb_s=2.0,
                                      hold_s=1.5)  # fmt: skip
        else:
            plan = swap_plan(top_type=type_name, bottom_type=type_name, vertical_gap_m=gap_m, cross_offset_m=0.03,
                             centre_m=(0.0, 0.0, SWAP_CENTRES_Z_M[k]), n_swaps=2, swap_s=2.5)  # fmt: skip
        flown = simulate_plan(plan, truth_effects=list(effects), seed=k + SEED_STRIDE * replicate)
        manifest = write_flight_logs(flown, root, flight_name=f"f{k}", split=split)
    return manifest
