"""Evaluation on benchmark sequences.

``datasets`` (the OTB and MIL layouts), ``jobs`` / ``worker`` / ``running``
(running trackers over sequences, here, in fresh processes or on Dask),
``results`` (the result files between running and scoring), ``scoring``,
``metrics`` and ``confidence`` (pure functions on result files),
``evaluation`` (the two in turn), ``report`` / ``plots`` / ``html_report`` /
``attributes`` / ``compare`` (tables and figures).  ``vidtrack eval`` is
:mod:`vidtrack.cli.eval`.
"""
