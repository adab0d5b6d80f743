"""GLSL sources, found with importlib.resources."""
