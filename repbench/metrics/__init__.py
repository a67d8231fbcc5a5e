"""Metric implementations, one module per family (pure functions on arrays)."""
