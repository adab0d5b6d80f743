"""glint: real-time walkthroughs of light-mapped scenes with measured-looking materials."""
__version__ = "0.1.0"
