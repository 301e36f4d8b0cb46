"""Offline runs over a dataset's flights or a recording, their metrics and reports."""
