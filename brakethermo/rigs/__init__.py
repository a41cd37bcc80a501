"""Rig physics: pure functions, one concept per module."""
