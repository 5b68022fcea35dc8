"""The autograder, in the order a submission travels from file to gradebook row.

``course`` reads the batch (names, labs, roster) -> ``loading`` finds the cells a
kernel needs -> ``running`` runs the hidden tests (pytest, in the grader) against a
proxy -> ``isolation`` runs the student's code in a confined worker -> ``wire`` brings
its results back as plain data -> ``course`` writes the gradebook, feedback and
exports; ``exports`` builds what leaves the instructor's machine (solved copies, the
student edition, Gradescope bundles). ``labs`` (where a lab's pieces live) and
``commands`` (the ``robolab`` sub-commands) sit at the top. See docs/architecture.md.
"""
