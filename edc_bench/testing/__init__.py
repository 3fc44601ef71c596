"""Helpers for testing edc-bench and the rigs it drives (fault injection)."""
