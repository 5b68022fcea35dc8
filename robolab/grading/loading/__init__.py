"""From a notebook file to the Python a kernel would have run: cells, names, guards.

Owns: ``notebook`` (the cells the exercises need), ``ipython_syntax`` (a cell as the
Python IPython makes of it), ``bindings`` (what a statement binds surely or maybe,
reads, and whether it is opaque), ``kernel`` (run those cells as Jupyter would, in a
``__main__`` module and its folder), ``magics`` (``%%writefile`` and ``%run`` inside
that folder), ``delegation`` (the library's answers disabled while an exercise is
graded). May import: ``robolab.grading.labs`` and the standard library; never the
answers.
"""
