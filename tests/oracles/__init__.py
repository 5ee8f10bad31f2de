"""Independent closed forms the tests check the general kinematics against (not shipped)."""
