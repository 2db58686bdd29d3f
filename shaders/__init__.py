"""GLSL sources for glref, shipped as package data (loaded with importlib.resources)."""
