"""A course's batch around the grading: names, roster, late policy, overrides, outputs.

Owns: ``batch`` (durable output folder, resuming, lab of each submission), ``roster``,
``late``, ``overrides``, ``report`` (gradebook rows and per-student feedback), ``lms``
(Canvas and Moodle files), ``outputs`` (one batch's outputs joined with the course),
``spreadsheet`` (the CSV writer every CSV goes through: no cell a spreadsheet evaluates),
``class_report`` (report.html for the instructor), ``shards`` and ``merge`` (a batch
graded in slices on many machines, joined again), ``similarity`` (pairs of submissions'
exercise code compared, parsed and never run).
May import: ``running`` (for ``SubmissionResult``), ``loading`` (the notebook's cells, for
``similarity``) and ``labs``; never ``isolation``.
"""
