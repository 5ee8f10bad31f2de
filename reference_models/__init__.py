"""The MuJoCo reference model of a scene."""
