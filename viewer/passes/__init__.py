"""Render passes, one module each."""
