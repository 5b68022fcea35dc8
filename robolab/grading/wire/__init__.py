"""Plain data across the worker boundary: the bounded decoder and call observation.

Owns: ``codec`` (decode a worker's message at a cost the grader bounds), ``unpickler``
(its allow-list engine), ``observe`` (in-place changes and aliasing, replayed on the
grader's arrays), ``depcall`` (the worker's stubs that ask the grader for an answer).
May import: numpy and the standard library only; nothing else of the grader, so that
both sides of the boundary can load it.
"""
