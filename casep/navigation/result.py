"""The navigation solution: strapdown telemetry, how it was aligned, and the checks a reader wants."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.frames import LaunchSite
from casep.io.pair import VALID_COLUMN
from casep.navigation.alignment import Alignment

__all__ = ["NavigationResult", "TELEMETRY_COLUMNS", "VALID_COLUMN"]

#: The strapdown telemetry columns :meth:`NavigationResult.columns` gives, in order.
TELEMETRY_COLUMNS = ("t", "q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z", "w_x", "w_y", "w_z",
                     "v_tel_x", "v_tel_y", "v_tel_z", "r_tel_x", "r_tel_y", "r_tel_z")


@dataclass
class NavigationResult:
    """A strapdown navigation solution in the launch-inertial frame.

    Attributes
    ----------
    t : (N,) ndarray
        Times, s (from the alignment window's first sample).
    q : (N, 4) ndarray
        Attitude: Hamilton quaternion, scalar first, rotating body vectors into the launch-inertial frame.
    fb, w : (N, 3) ndarray
        Body specific force (m/s^2) and rate (rad/s) as measured (increments: over their sample period).
    v, r : (N, 3) ndarray
        Launch-inertial velocity (m/s) and position (m).
    site : LaunchSite
    alignment : Alignment
    kind : str
        The input: ``"rates"`` or ``"increments"``.
    gaps : int
        Steps with lost samples, integrated across.
    passes : int
        The most fixed-point passes a window of the gravity iteration needed.
    valid : (N,) ndarray of bool or None
        False from the first clipped IMU sample on (the solution is wrong there); None: nothing clipped.
        Written as the column :data:`VALID_COLUMN` (1 or 0) when some sample is not valid.
    steps_said : str or None
        What the record's steps between samples leave unknown (:func:`casep.navigation.imu.steps_said`); None: none.
    """

    t: np.ndarray
    q: np.ndarray
    fb: np.ndarray
    w: np.ndarray
    v: np.ndarray
    r: np.ndarray
    site: LaunchSite
    alignment: Alignment | None
    kind: str = "rates"
    gaps: int = 0
    passes: int = 1
    source: str = "<memory>"
    align_window: tuple[float, float] = (0.0, 0.0)
    settings: dict = field(default_factory=dict)
    valid: np.ndarray | None = None
    steps_said: str | None = None

    def columns(self) -> dict[str, np.ndarray]:
        """The strapdown telemetry as named columns (:data:`TELEMETRY_COLUMNS`, and :data:`VALID_COLUMN` when
        some sample is not valid)."""
        arrays = [self.t[:, None], self.q, self.fb, self.w, self.v, self.r]
        out = dict(zip(TELEMETRY_COLUMNS, np.hstack(arrays).T))
        if self.invalid_from() is not None:
            out[VALID_COLUMN] = np.asarray(self.valid, float)
        return out

    def comments(self, imu: str) -> list[str]:
        """The header lines of the telemetry file written from `imu` (the frame and the launch site, which
        :func:`casep.io.files.navigation_site` reads back; the quaternion convention; the pad alignment, which
        :func:`casep.io.files.levelling_record` reads back; the validity column)."""
        s = self.site
        from casep.io.files import levelled_comment

        clipped = [f"{VALID_COLUMN}: 0 from the first clipped IMU sample on (not trusted)"]
        return [f"casep navigate {imu}: strapdown telemetry, launch-inertial frame",
                f"launch site {s.lat_deg:.12g} {s.lon_deg:.12g} {s.h_m:.12g} azimuth {s.azimuth_deg:.12g} deg, "
                f"launch time {s.t0:.12g} s", "q: Hamilton, scalar first, body -> launch-inertial; SI units"] + \
            ([levelled_comment(self.align_window, self.alignment)] if self.alignment is not None else []) + \
            (clipped if self.invalid_from() is not None else [])

    def invalid_from(self) -> float | None:
        """The time of the first sample whose solution is not valid (a clipped IMU sample), s; None: all valid."""
        if self.valid is None or bool(np.all(self.valid)):
            return None
        return float(self.t[np.argmin(self.valid)])

    def earth_relative(self) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity relative to the rotating Earth (ECEF, m, m/s): :func:`casep.frames.launch_to_ecef`."""
        from casep.frames import launch_to_ecef

        return launch_to_ecef(self.site, self.t, self.r, self.v)

    def pad_drift(self) -> float:
        """Largest speed relative to the Earth over the alignment window, m/s (at rest: zero, up to the sensors)."""
        _, v_e = self.earth_relative()
        sel = self.t <= self.align_window[1]
        return float(np.max(np.linalg.norm(v_e[sel], axis=1)))

    @property
    def success(self) -> bool:
        """Whether every window of the gravity iteration converged."""
        from casep.navigation.strapdown import MAX_PASSES

        return self.passes <= MAX_PASSES

    @property
    def status(self) -> int:
        """0 navigated, 1 the gravity iteration did not converge in some window."""
        return 0 if self.success else 1

    @property
    def message(self) -> str:
        """One line: what was navigated."""
        if not self.success:
            return "navigated, but the gravity iteration did not converge in some window: the solution is unreliable"
        how = f"aligned by {self.alignment.method}" if self.alignment is not None else "from a given state"
        return f"navigated {len(self.t)} samples ({self.t[-1] - self.t[0]:.6g} s) from {self.kind}, {how}"

    def to_dict(self) -> dict[str, Any]:
        """Plain data: the set-up, the alignment, the pad check and the end state (not the time series)."""
        r_e, v_e = self.earth_relative()
        return {"success": self.success, "status": self.status, "message": self.message, "source": self.source,
                "input": self.kind, "samples": int(len(self.t)), "t_start": float(self.t[0]),
                "t_end": float(self.t[-1]), "site": self.site.to_dict(), "align_window": list(self.align_window),
                "alignment": None if self.alignment is None else self.alignment.to_dict(), "gaps": self.gaps,
                "gravity_passes": self.passes, "pad_drift_m_s": self.pad_drift(),
                "invalid_from_s": self.invalid_from(), "steps": self.steps_said,
                "end": {"v_tel": self.v[-1].tolist(), "r_tel": self.r[-1].tolist(), "v_ecef": v_e[-1].tolist(),
                        "r_ecef": r_e[-1].tolist()}}

    def text(self) -> str:
        """What the command line prints."""
        from casep.frames import ecef_to_geodetic

        a = self.alignment
        r_e, v_e = self.earth_relative()
        lat, lon, h, ve, vn, vu = ecef_to_geodetic(r_e[-1:], v_e[-1:])
        lines = [self.message,
                 f"  input      {self.source}: {self.kind}, {len(self.t)} samples from t = {self.t[0]:.6g} s to "
                 f"{self.t[-1]:.6g} s" + (f", {self.gaps} gap(s) integrated across" if self.gaps else "")]
        if a is not None:
            lines += self._alignment_lines(a)
        if self.steps_said is not None:
            lines.append(f"  steps      {self.steps_said}")
        if self.invalid_from() is not None:
            lines.append(f"  clipped    the IMU clipped at t = {self.invalid_from():.10g} s: the solution from there "
                         f"on is marked {VALID_COLUMN} = 0 (the separation leaves it out)")
        lines += [f"  end        t = {self.t[-1]:.6g} s: lat {lat[0]:.6f} deg, lon {lon[0]:.6f} deg, h {h[0]:.1f} m; "
                  f"velocity east {ve[0]:.2f}, north {vn[0]:.2f}, up {vu[0]:.2f} m/s (relative to the Earth)",
                  f"  frame      launch-inertial (t0 = {self.site.t0:g} s, azimuth {self.site.azimuth_deg:g} deg); "
                  "columns t, q_w..q_z (body -> launch, scalar first), fb_*, w_*, v_tel_*, r_tel_*"]
        return "\n".join(lines)

    def _alignment_lines(self, a: Alignment) -> list[str]:
        head = (f"heading given: body {a.heading_axis} at {a.heading_deg:.3f} deg" if a.method == "heading" else
                f"heading by gyrocompassing: body {a.heading_axis} at {a.heading_deg:.2f} deg, known to about "
                f"{a.heading_std_deg:.2g} deg")
        up = a.f_mean / np.linalg.norm(a.f_mean)
        return [f"  alignment  {self.align_window[0]:g} .. {self.align_window[1]:g} s ({a.rows} samples): |f| = "
                f"{np.linalg.norm(a.f_mean):.5f} m/s^2 (normal gravity {a.g_pad:.5f}); up in body axes "
                f"({up[0]:.4f}, {up[1]:.4f}, {up[2]:.4f}); {head}",
                f"  pad check  largest speed relative to the Earth over the window: {self.pad_drift():.3g} m/s"]
