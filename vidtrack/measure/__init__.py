"""Measurers: turn a frame and a prior into a measurement."""
