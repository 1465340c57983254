"""Readers of the benchmark layouts as they are downloaded, one module each.

Each module offers ``is_sequence(folder)`` (a folder is one of its
sequences), ``is_dataset(folder)`` (a folder of its sequences) and
``entries(folder)``: ``{sequence name: loader}``, where calling a loader reads
that sequence (a :class:`~vidtrack.eval.sequence.BenchmarkSequence`) or raises
:class:`~vidtrack.errors.DatasetError` with the reason it cannot.
"""
