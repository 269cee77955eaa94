"""The launch site of ``--launch-site LAT LON H AZ`` and ``--launch-time T0``, its refusals named by the option."""

from __future__ import annotations

from typing import Any

__all__ = ["launch_site"]


def launch_site(values: list[float], t0: float) -> Any:
    """The :class:`casep.frames.LaunchSite` of ``--launch-site LAT LON H AZ`` and a launch time `t0`."""
    from casep.frames import LaunchSite

    lat, lon, h, az = values
    try:
        return LaunchSite(lat, lon, h, az, t0)
    except ValueError as e:  # the site's own rule, said with the option that gave the value
        option = next((o for f, o in _SITE_OPTIONS.items() if f"`{f}`" in str(e)), None)
        if option is None:
            raise
        raise ValueError(f"{option}: {e}") from None


#: LaunchSite's fields and the command-line option each comes from.
_SITE_OPTIONS = {"lat_deg": "--launch-site LAT", "lon_deg": "--launch-site LON", "h_m": "--launch-site H",
                 "azimuth_deg": "--launch-site AZ", "t0": "--launch-time T0"}
