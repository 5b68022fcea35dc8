"""The C library as the sandbox calls it: syscalls, with a failure raised as SandboxError."""

from __future__ import annotations

import ctypes
import os

__all__ = ["SandboxError", "pad_heap"]


class SandboxError(OSError):
    """A step of the sandbox that was planned could not be applied."""


def _libc() -> ctypes.CDLL:
    # The running interpreter already links libc; find_library would spawn ldconfig.
    libc = ctypes.CDLL(None, use_errno=True)
    libc.syscall.restype = ctypes.c_long
    return libc


def _check(result: int, what: str) -> int:
    if result < 0:
        code = ctypes.get_errno()
        raise SandboxError(code, f"{what}: {os.strerror(code)}")
    return result


#: glibc's mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
#: The largest M_MMAP_THRESHOLD glibc accepts on 64-bit systems (HEAP_MAX_SIZE / 2).
_MMAP_THRESHOLD_MAX = 1 << 25


def pad_heap(keep_bytes: int = 1 << 26) -> bool:
    """Let malloc keep up to ``keep_bytes`` of freed memory instead of returning it at once.

    numpy's temporaries of a few MB (a filter step over 20 000 particles makes dozens)
    are each mapped afresh by default and handed back when freed, so every step faults
    every page in again (680 000 minor faults and 1 s of system time in lab 05's
    global-localization test). With arrays below 32 MiB taken from the heap, which grows
    ``keep_bytes`` at a time and is trimmed only once ``keep_bytes`` are free at its top,
    the same pages are reused: the resident memory of the process stays at its peak plus
    at most ``keep_bytes``. Returns False where there is no glibc ``mallopt`` (nothing
    changes).
    """
    try:
        mallopt = _libc().mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(
        mallopt(_M_MMAP_THRESHOLD, min(keep_bytes, _MMAP_THRESHOLD_MAX))
        and mallopt(_M_TRIM_THRESHOLD, keep_bytes)
        and mallopt(_M_TOP_PAD, keep_bytes)
    )
