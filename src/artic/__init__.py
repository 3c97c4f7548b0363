"""artic: structured robotic manipulation as a typed command-line toolkit."""

__version__ = "0.1.0"
