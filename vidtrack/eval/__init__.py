"""Evaluation on benchmark sequences: datasets, metrics, experiment runner, plots."""
