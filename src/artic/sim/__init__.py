"""PyBullet worlds: connections now; robots and task environments later (Chapter 5)."""
