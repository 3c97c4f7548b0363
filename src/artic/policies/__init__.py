"""Policy classes: dynamic movement primitives and Gaussian MLP policies (Chapter 5)."""
