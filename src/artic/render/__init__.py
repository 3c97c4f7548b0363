"""Depth rendering backends, the Kinect-like sensor model and dataset previews."""
