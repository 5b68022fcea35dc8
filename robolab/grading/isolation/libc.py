"""The C library as the sandbox calls it: syscalls, with a failure raised as SandboxError."""

from __future__ import annotations

import ctypes
import os

__all__ = ["SandboxError"]


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
