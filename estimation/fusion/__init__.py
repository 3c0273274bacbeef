"""Fusion filters of the flight software: Balaram's kinematic EKF (seed 001)."""
