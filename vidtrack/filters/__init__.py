"""Filters: recursive (robust) estimators of the target box."""
