"""Physical constants of Mars that the flight software and the simulator share.

Sources are on each line; see docs/REFERENCES.md.
"""

MARS_GRAVITY_M_S2 = 3.711  # NASA Mars fact sheet, equatorial surface gravity
MARS_EQUATORIAL_RADIUS_M = 3_396_190.0  # IAU/IAG 2000 reference ellipsoid (docs/REFERENCES.md)
MARS_POLAR_RADIUS_M = 3_376_200.0  # IAU/IAG 2000 reference ellipsoid (docs/REFERENCES.md)
MARS_GM_M3_S2 = 4.282837e13  # JPL, GM of Mars
MARS_ROTATION_DEG_PER_DAY = 350.89198226  # IAU 2009, dW/dd of the prime meridian
MARS_ROTATION_RATE_RAD_S = 7.0882181e-5  # the above in rad/s (350.89198226 deg / 86400 s)
