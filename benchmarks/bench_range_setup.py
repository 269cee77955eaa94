"""Set-up checks of range data: a rotating-Earth flight (Florida, due east; 20 Hz telemetry and ECEF
tracking, white noise 0.1 m/s) read back with the right set-up and with set-up mistakes.

Run: ``python benchmarks/bench_range_setup.py`` (about 20 s). Prints one Markdown table row per case:
the pad-velocity mismatch, the first tracked position's distance from the stated site, the turn about the
vertical, the coarse time offset and the share of the misfit it removes, and the result's status.
"""

from __future__ import annotations

import dataclasses
import tempfile
import warnings
from pathlib import Path

import casep
from casep.frames import LaunchSite
from casep.simulation.simulate import simulate_two_rate

SITE = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)
CASES = [("right set-up", {}), ("site 36 deg north (3936 km)", {"lat_deg": 64.5}),
         ("site 40.6 deg east (3892 km)", {"lon_deg": -40.0}), ("azimuth +10 deg", {"azimuth_deg": 100.0}),
         ("azimuth +0.1 deg", {"azimuth_deg": 90.1}), ("launch time +1 h", {"t0": 3600.0})]


def main() -> None:
    d = simulate_two_rate("paper", seed=0, telemetry_rate=20.0, tracking_rate=20.0, rotating_earth=True, site=SITE)
    with tempfile.TemporaryDirectory() as tmp:
        tel, trk = Path(tmp) / "tel.csv", Path(tmp) / "trk.csv"
        d.write(tel, trk, tracking_frame="ecef")
        print("| case | pad velocity mismatch, m/s | first tracked point from site, km | turn about vertical, deg "
              "| coarse offset, ms (misfit removed) | status |")
        print("|---|---|---|---|---|---|")
        for label, change in CASES:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fl = casep.read_flight_pair(tel, trk, tracking_frame="ecef", site=dataclasses.replace(SITE, **change))
                res = casep.separate(fl, "platform36")
            ev, a = fl.meta["setup"], fl.meta["time_alignment"]
            print(f"| {label} | {ev['pad']['speed_relative_m_s']:.3g} | "
                  f"{ev['first_tracked']['distance_from_site_m'] / 1e3:.4g} | "
                  f"{ev['pad']['turn_about_vertical_deg']:.3g} "
                  f"| {1e3 * a['tau_s']:.3g} ({100 * a['gain']:.2g} %) | {res.status} "
                  f"{'success' if res.success else 'failed'} |")


if __name__ == "__main__":
    main()
