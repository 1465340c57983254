"""Sinks: where TrackStates go (boxes file, CSV log, annotated video, Rerun)."""
