"""What leaves the instructor's machine: solved copies, the student edition, Gradescope.

Owns: ``solve`` (exercise cells replaced by the reference), ``release`` (the student
edition: no solutions, no hidden tests), ``gradescope`` (the autograder bundle and the
step that runs inside it). May import: every other layer of the grader.
"""
