"""Sinks: where TrackStates go (boxes file, CSV log, exports, annotated video, Rerun)."""
