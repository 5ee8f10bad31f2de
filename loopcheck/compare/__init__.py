"""Comparison of the reduced solver and the MuJoCo reference, and the ``loopcheck`` CLI."""
