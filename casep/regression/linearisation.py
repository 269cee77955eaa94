"""When a linearised time term is re-solved at its estimate: one rule for the tracking offset and the launch time.

A time correction ``dt`` estimated through its first-order column (the tracking offset ``dt_trk``:
``v(t - dt) ~ v(t) - a dt``; the radar launch time ``dt_launch``: ``h(t0 + dt) ~ h(t0) + (d h / d t0) dt``)
leaves out its second-order term. While that term is below :data:`LINEAR_OFFSET_SHARE` of the std it is
measured against, the linear column holds; beyond it the data are re-formed at the correction found and
fitted again, until every rest is within its std or within what the linearisation holds, at most
:data:`MAX_REPAIRS` times (else the result fails). Users: :func:`casep.workflows.separate.repair_on_offset`
(the term as an offset against the offset's std), :func:`casep.workflows.radar.separate_radar` (the term's
shift of every estimate against its std), :func:`casep.workflows.telemetry_iterate.iterate_if_curved` (a strapdown
telemetry's second-order remainder: its shift of the estimate along the combination it moves most, in that
combination's std).
"""

from __future__ import annotations

__all__ = ["MAX_REPAIRS", "LINEAR_OFFSET_SHARE"]

#: Re-formings of the data at the estimated time correction (each a fit) before it is called not settled.
MAX_REPAIRS = 6
#: The linearised time term holds while the term it leaves out is below this share of the std it is measured against.
LINEAR_OFFSET_SHARE = 0.1
