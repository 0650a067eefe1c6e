"""Short human-readable summary of a plan (summary.txt beside plan.json) and of verify results."""

from __future__ import annotations

from proxplan.planfile import Plan


def _fmt(value, unit: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3f}{unit}"
    return f"{value}{unit}"


def plan_summary(plan: Plan, *, violations: list | None = None) -> str:
    """A few lines: method, makespan, worst authority usage, separation, per-vehicle figures, notes."""
    m = plan.metrics
    lines = [
        f"plan of scenario '{plan.scenario}' ({plan.method}), {len(plan.vehicles)} vehicles, dt {plan.dt_s:g} s",
        f"  makespan {_fmt(m.get('makespan_s'), ' s')}, planned in {_fmt(m.get('planning_time_s'), ' s')}",
        f"  max authority usage {_fmt(m.get('max_authority_usage'))} (limit {_fmt(m.get('authority_fraction'))}), "
        f"min separation {_fmt(m.get('min_separation_m'), ' m')}"
        + (
            f", docked pairs down to {_fmt(m.get('min_dock_separation_m'), ' m')}"
            if m.get("min_dock_separation_m") is not None
            else ""
        ),
    ]
    if plan.solver is not None:
        st = plan.solver
        lines.append(
            f"  optimiser ({st.method}): IPOPT {st.return_status}, {st.iterations} iterations in {st.solves} solve(s), "
            f"{st.solve_time_s:.2f} s, constraint violation {st.constraint_violation:.1e}, objective {st.objective:.3f}"
            + ("" if st.converged else " (not used: fell back to the sampling plan)")
        )
    usage = m.get("authority_usage_by_vehicle", {})
    length = m.get("path_length_m", {})
    invalid = m.get("invalid_zone_s_by_vehicle", {})
    for name, tr in plan.vehicles.items():
        extra = f", {invalid[name]:.2f} s in a source's invalid zone" if invalid.get(name) else ""
        lines.append(
            f"  {name} ({tr.type_name}): path {_fmt(length.get(name), ' m')}, max usage {_fmt(usage.get(name))}{extra}"
        )
    for note in plan.notes:
        lines.append(f"  note: {note}")
    if violations is not None:
        lines.append(f"  verify: {'PASS' if not violations else f'{len(violations)} violation(s)'}")
        lines.extend(f"    {v}" for v in violations)
    return "\n".join(lines) + "\n"
