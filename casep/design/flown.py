"""A designed manoeuvre against the flights that fly it: did the design model keep its promise?

:func:`casep.design.optimize.design` optimises the objective on a design model (a coarse grid,
the nominal specific force turned by the attitude offset) and then re-flies the nominal and the
designed flight through the vehicle model (``DesignResult.verification``). The relative change of
the objective promised by the design model,

    g_design = (J_before - J_after) / |J_before|,

and the one the re-simulated flights give, g_flown (the same with the verification's values), are
compared by :func:`promise_check`; they disagree when |g_design - g_flown| > 5 % of |g_flown| and
> 0.01 (one percentage point), and then the re-simulated value is the one to trust.
:func:`design_lines` is the report ``casep design`` prints.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["PromiseCheck", "promise_check", "relative_change", "design_lines", "RTOL", "ATOL"]

#: Relative and absolute tolerance on the change of the objective (design model against flown).
RTOL, ATOL = 0.05, 0.01


def relative_change(before: float, after: float) -> float:
    """(before - after) / |before|: the fraction by which the objective fell (0 when before is 0)."""
    return (before - after) / abs(before) if before else 0.0


@dataclass(frozen=True)
class PromiseCheck:
    """The objective's relative change promised by the design model and given by the flown flights."""

    design_change: float
    flown_change: float

    @property
    def kept(self) -> bool:
        """True when the two agree within :data:`RTOL` (relative) or :data:`ATOL` (absolute)."""
        gap = abs(self.design_change - self.flown_change)
        return not (gap > RTOL * max(abs(self.flown_change), 1e-12) and gap > ATOL)

    def warning(self) -> str | None:
        """The warning line when the promise is not kept, else None."""
        if self.kept:
            return None
        return (f"warning: the design model promised a {100 * self.design_change:.1f} % change of the objective, the "
                f"re-simulated flights give {100 * self.flown_change:.1f} %: trust the re-simulated value (the JSON's "
                "before/after)")


def promise_check(res: Any) -> PromiseCheck:
    """Compare the design model's change of the objective with the re-simulated flights'.

    Parameters
    ----------
    res : DesignResult
        :func:`casep.design.optimize.design`'s result. Without a verification (one's own trajectory:
        no vehicle to re-fly) the flown change is the promised one.

    Returns
    -------
    PromiseCheck
    """
    g_design = relative_change(res.before, res.after)
    v = res.verification
    return PromiseCheck(g_design, relative_change(v["before"], v["after"]) if v else g_design)


def design_lines(res: Any, *, scenario: str, maneuver: str, own_flight: str | None = None) -> list[str]:
    """The report of a design: objective before/after, solver, verification, burnout change, manoeuvre, table.

    Parameters
    ----------
    res : DesignResult
    scenario : str
        The nominal flight's scenario name.
    maneuver : str
        ``yaw``, ``pitch`` or ``both``.
    own_flight : str, optional
        One's own trajectory file (then nothing is re-flown).

    Returns
    -------
    list of str
    """
    from casep.simulation.scenarios import get_scenario

    s, v = res.solver, res.verification
    lines = [f"{res.objective}-optimal {maneuver} manoeuvre, scenario {scenario}: objective {res.before:.6g} -> "
             f"{res.after:.6g} (design model); IPOPT {s['return_status']} (best of {len(s['starts'])} starts; "
             f"{sum(r['success'] for r in s['starts'])} solved), {res.timing['total']:.1f} s"]
    if not v:  # one's own trajectory: no vehicle to re-fly
        lines.append(f"own trajectory {own_flight}: the designed flight is not re-flown (no vehicle model); the "
                     "'after' bounds are the design model's prediction (the manoeuvre turns the specific force)")
    else:
        lines.append(f"re-simulated: objective {v['before']:.6g} -> {v['after']:.6g}; CRLB prediction error max "
                     f"{100 * v['crlb_prediction_error_max']:.1f} %")
    warning = promise_check(res).warning()
    if warning:
        lines.append(warning)
    if v:
        b = v["burnout_change"]
        lines.append(f"the designed flight burns out elsewhere: speed {b['speed_m_s']:+.1f} m/s, altitude "
                     f"{b['altitude_m'] / 1e3:+.2f} km, crossrange {b['crossrange_m'] / 1e3:+.2f} km (no terminal "
                     "constraint: a test flight, not the mission)")
    sc_noise = get_scenario(scenario).noise
    if sc_noise.kind != "white" and not own_flight:
        lines.append(f"warning: scenario {scenario} has {sc_noise.kind} tracking noise; the design assumes white "
                     "noise of the same sigma")
    m = res.maneuver.to_dict(res.x)
    lines.append("knots s:   " + " ".join(f"{t:7.1f}" for t in m["knots_s"]))
    lines += [f"{axis + ' deg:':<11}" + " ".join(f"{a:7.2f}" for a in m[f"{axis}_deg"]) for axis in res.maneuver.axes]
    lines.append(res.crlb_table())
    what = "posterior std (prior included) < declared magnitude" if res.prior else "CRLB < declared magnitude"
    lines.append(f"identifiable ({what}): {len(res.identifiable('before'))} before, "
                 f"{len(res.identifiable('after'))} after: {', '.join(res.identifiable('after')) or 'none'}")
    if res.worse():
        lines.append(f"worse after the design (bound x > 1.05): {', '.join(res.worse())}")
    return lines
