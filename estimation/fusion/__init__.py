"""Fusion filters of the flight software: Balaram's kinematic EKF (Balaram 2000)."""
