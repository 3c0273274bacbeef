"""MER stereo visual odometry (Maimone, Cheng and Matthies 2007, seed 002, section 2)."""
