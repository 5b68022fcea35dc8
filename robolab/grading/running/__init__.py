"""The hidden tests run in the grader against a proxy of the student's functions.

Owns: ``proxy`` (the grader's side of a worker: calls, limits, results), ``runner``
(one pytest run per submission, in parallel, into ``SubmissionResult``),
``pytest_plugin`` (the ``lab`` fixture, points per exercise, hints). May import:
``wire``, ``loading``, ``isolation``, ``labs``. This is the only layer that holds the
hidden tests and the reference solutions.
"""
