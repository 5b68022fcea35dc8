"""Landlock (Linux >= 5.13): the path- and network-level wall a worker raises around itself.

An unprivileged process can apply it to itself; each ABI version adds rights (2: refer,
3: truncate, 4: TCP, 5: device ioctl, 6: abstract unix sockets and signals). Used by
:func:`robolab.grading.isolation.sandbox.apply`.
"""

from __future__ import annotations

import ctypes
import errno
import os
import platform
import stat
import sys

from robolab.grading.isolation.libc import _check, _libc

__all__ = ["landlock_abi", "restrict"]

_SYS_LANDLOCK = {"x86_64": (444, 445, 446), "aarch64": (444, 445, 446), "arm64": (444, 445, 446)}
_LANDLOCK_CREATE_RULESET_VERSION = 1 << 0
_LANDLOCK_RULE_PATH_BENEATH = 1

_FS_EXECUTE = 1 << 0
_FS_WRITE_FILE = 1 << 1
_FS_READ_FILE = 1 << 2
_FS_READ_DIR = 1 << 3
_FS_REFER = 1 << 13  # ABI 2
_FS_TRUNCATE = 1 << 14  # ABI 3
_FS_IOCTL_DEV = 1 << 15  # ABI 5
_NET_BIND_TCP = 1 << 0  # ABI 4
_NET_CONNECT_TCP = 1 << 1  # ABI 4
_SCOPE_ABSTRACT_UNIX_SOCKET = 1 << 0  # ABI 6
_SCOPE_SIGNAL = 1 << 1  # ABI 6


def _fs_rights(abi: int) -> int:
    rights = (1 << 13) - 1  # ABI 1: bits 0..12
    if abi >= 2:
        rights |= _FS_REFER
    if abi >= 3:
        rights |= _FS_TRUNCATE
    if abi >= 5:
        rights |= _FS_IOCTL_DEV
    return rights


class _RulesetAttr(ctypes.Structure):
    _fields_ = [
        ("handled_access_fs", ctypes.c_uint64),
        ("handled_access_net", ctypes.c_uint64),
        ("scoped", ctypes.c_uint64),
    ]


class _PathBeneathAttr(ctypes.Structure):
    _pack_ = 1  # the kernel struct is __attribute__((packed)): 12 bytes
    _fields_ = [("allowed_access", ctypes.c_uint64), ("parent_fd", ctypes.c_int32)]


def landlock_abi() -> int:
    """The kernel's Landlock ABI version, 0 when Landlock is unavailable.

    Landlock is unavailable on kernels before 5.13, when it is not enabled at
    boot (``lsm=``), on architectures whose syscall numbers are not known here,
    and on systems other than Linux.
    """
    if sys.platform != "linux":
        return 0
    numbers = _SYS_LANDLOCK.get(platform.machine())
    if numbers is None:
        return 0
    libc = _libc()
    abi = libc.syscall(
        numbers[0], None, ctypes.c_size_t(0), ctypes.c_uint32(_LANDLOCK_CREATE_RULESET_VERSION)
    )
    return max(int(abi), 0)


def restrict(
    libc: ctypes.CDLL, abi: int, readonly: list[str], workdir: str, devices: tuple[str, ...]
) -> None:
    """Confine this process: read ``readonly`` and ``devices``, write ``workdir``; no TCP,
    and with ABI 6 no abstract unix sockets or signals outside its domain."""
    create, add_rule, restrict = _SYS_LANDLOCK[platform.machine()]
    handled = _fs_rights(abi)
    attr = _RulesetAttr(handled_access_fs=handled)
    size = 8
    if abi >= 4:
        attr.handled_access_net = _NET_BIND_TCP | _NET_CONNECT_TCP  # no rules: all TCP denied
        size = 16
    if abi >= 6:
        attr.scoped = _SCOPE_ABSTRACT_UNIX_SOCKET | _SCOPE_SIGNAL
        size = 24
    ruleset = _check(
        libc.syscall(create, ctypes.byref(attr), ctypes.c_size_t(size), ctypes.c_uint32(0)),
        "landlock_create_ruleset",
    )
    file_rights = (
        _FS_EXECUTE | _FS_WRITE_FILE | _FS_READ_FILE | (handled & (_FS_TRUNCATE | _FS_IOCTL_DEV))
    )
    read = _FS_EXECUTE | _FS_READ_FILE | _FS_READ_DIR
    try:
        for path in readonly:
            _allow(libc, add_rule, ruleset, path, read)
        for device in devices:
            rights = file_rights if device == "/dev/null" else _FS_READ_FILE
            _allow(libc, add_rule, ruleset, device, rights)
        _allow(libc, add_rule, ruleset, workdir, handled)
        _check(
            libc.syscall(restrict, ctypes.c_int(ruleset), ctypes.c_uint32(0)),
            "landlock_restrict_self",
        )
    finally:
        os.close(ruleset)


def _allow(libc: ctypes.CDLL, add_rule: int, ruleset: int, path: str, rights: int) -> None:
    try:
        fd = os.open(path, os.O_PATH | os.O_CLOEXEC)
    except FileNotFoundError:
        return
    try:
        if not stat.S_ISDIR(os.fstat(fd).st_mode):
            # Directory-only rights on a file make the kernel refuse the rule.
            rights &= _FS_EXECUTE | _FS_WRITE_FILE | _FS_READ_FILE | _FS_TRUNCATE | _FS_IOCTL_DEV
        rule = _PathBeneathAttr(allowed_access=rights, parent_fd=fd)
        result = libc.syscall(
            add_rule,
            ctypes.c_int(ruleset),
            ctypes.c_int(_LANDLOCK_RULE_PATH_BENEATH),
            ctypes.byref(rule),
            ctypes.c_uint32(0),
        )
        if result < 0 and ctypes.get_errno() != errno.ENOENT:
            _check(result, f"landlock_add_rule {path}")
    finally:
        os.close(fd)
