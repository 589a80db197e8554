"""Validation against exact and reference solutions: Hertz, Cattaneo-Mindlin, and a tight reference solve of a scene."""
