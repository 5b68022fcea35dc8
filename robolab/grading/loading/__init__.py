"""From a notebook file to the Python a kernel would have run: cells, names, guards.

Owns: ``notebook`` (cells through IPython's transformation, names by ``symtable``, the
cells the exercises need), ``kernel`` (run those cells as Jupyter would), ``delegation``
(the library's answers disabled while an exercise is graded). May import:
``robolab.grading.labs`` and the standard library; never the answers.
"""
