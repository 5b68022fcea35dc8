"""The student's code in a confined process: the operating system keeps the answers out.

Owns: ``sandbox`` (namespaces, mounts, rlimits), ``landlock`` (the path and network
wall), ``libc`` (the syscalls), ``seccomp`` (no signals to other
processes), ``processes`` (CPU time of a worker's process tree, the sweep), ``worker``
(the confined process), ``zygote``/``warm`` (forking workers from a clean process),
``protection`` (what this machine protects, probed once per batch). May import:
``wire`` and ``loading``; ``protection`` probes through ``running.proxy``, imported
lazily, since a probe is a real graded call.
"""
