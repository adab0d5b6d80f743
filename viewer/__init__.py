"""The viewer: reads a bake directory and renders it (window or headless)."""
