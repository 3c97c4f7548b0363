"""Hydra composition of `conf/` and the pydantic schemas that validate it."""
