"""MER stereo visual odometry (Cheng, Maimone and Matthies 2005, section 2).

The front is ``odometry.VisualOdometry`` (tuned by ``params.VoParams``); one idea per module
beneath it: ``stereo_rig`` and ``geometry`` (the pointed pair in the body frame),
``features`` (Harris, grid, separation), ``correlation`` and ``search`` (pseudo-normalised
correlation, biquadratic subpixel peak), ``stereo`` and ``triangulation`` (eqs. 1-11),
``tracking`` (wheel-odometry-guided, coarse to fine), ``motion`` (eqs. 12-14 in RANSAC),
``ml_motion`` (eqs. 15-17) and ``sanity`` (the February 2005 constraints).
"""
