"""Passes on numpy arrays: the gaze-shift pass layered onto a base motion."""
