"""Fitting, comparison and reports: material calibration, validation, statistics."""
