"""The hidden tests run in the grader against a proxy of the student's functions.

Owns: ``proxy`` (the grader's side of a submission: calls, budgets, results),
``channel`` (one worker process: messages under limits, depcalls, the sweep), ``limits``
(the limits and how they scale with the reference's CPU), ``errors`` (what student code
can do wrong), ``answers`` (the reference answering a graded exercise's calls to the
exercises below it), ``runner`` (one pytest run per submission, in parallel, into
``SubmissionResult``), ``stopping`` (SIGINT and SIGTERM as a stop request; stopping the
pytest runs, bounded), ``pytest_plugin`` (the ``lab`` fixture, points per exercise) and
``credit`` (gates and hints across exercises). May import: ``wire``, ``loading``,
``isolation``, ``labs``. This is the only layer that holds the hidden tests and the
reference solutions.
"""
