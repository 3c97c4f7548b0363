"""SE(3), axes, frames and camera maths: pure numpy, no I/O."""
