"""A course's batch around the grading: names, roster, late policy, overrides, outputs.

Owns: ``batch`` (durable output folder, resuming, lab of each submission), ``roster``,
``late``, ``overrides``, ``report`` (gradebook rows and per-student feedback), ``lms``
(Canvas and Moodle files), ``outputs`` (one batch's outputs joined with the course),
``spreadsheet`` (the CSV writer every CSV goes through: no cell a spreadsheet evaluates).
May import: ``running`` (for ``SubmissionResult``) and ``labs``; never ``isolation``.
"""
