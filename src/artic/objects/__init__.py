"""Procedural articulated objects: sample a spec, build its parts, write it as URDF."""
