"""radar_biases: the systematic errors of one tracking radar (a tracking model, ``--tracking-model``).

Conventions (measured = true + error; a separation gives each station its own copy, ``S1.range_bias``):

- measured range = (1 + range_scale 1e-6) true range + range_bias
- measured azimuth = true azimuth + azimuth_bias; measured elevation = true elevation + elevation_bias
- time_bias tau: the value tagged t was measured at t - tau, so to first order
  measured(t) = true(t) - tau d(true)/dt  (range, angles and range rate alike; tau in ms)

A term of your own goes in a copy of this file (e.g. a residual refraction
``refraction * cos(E) / sin(E)`` in elevation, or a survey offset of the station along its axes:
``-(u . d)`` in range with u the line-of-sight unit vector ``model.enu / model.range``).
"""

import casep


def build():
    m = casep.TrackingModel("radar_biases", "range bias and scale, azimuth and elevation biases, time-tag bias")
    c = m.declare(range_bias=("m", 10.0), range_scale=("ppm", 20.0), azimuth_bias=("arcsec", 20.0),
                  elevation_bias=("arcsec", 20.0), time_bias=("ms", 1.0))
    tau = c.time_bias  # s (the declaration converts ms)
    m.set_range_error(c.range_scale * m.range + c.range_bias - tau * m.range_rate)
    m.set_azimuth_error(c.azimuth_bias - tau * m.azimuth_rate)
    m.set_elevation_error(c.elevation_bias - tau * m.elevation_rate)
    # the scale applies to the range rate as to the range; tagged late: -tau d(rho_dot)/dt
    m.set_range_rate_error(c.range_scale * m.range_rate - tau * m.range_acceleration)
    return m
