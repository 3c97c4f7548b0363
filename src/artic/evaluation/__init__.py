"""Metrics as pure functions, reports and plots."""
