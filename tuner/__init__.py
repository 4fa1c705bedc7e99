"""Tuner: identification, validation, diagnosis and reports for damper models."""
