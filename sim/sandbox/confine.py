"""What the guest does to itself before the untrusted code runs: resource limits, and no new
processes or threads.

The limits are the kernel's (`resource.setrlimit`): CPU seconds, address space, open files,
processes, no core files and no file growth. A process cannot raise a hard limit again. Process
and thread creation is refused by a seccomp filter (Linux x86-64 and arm64): `fork`, `vfork`,
`clone` and `clone3` fail with EPERM, and so do `ptrace` and `process_vm_readv/writev`. This
holds where RLIMIT_NPROC does not (it counts per user and does not bind root), and it keeps a
submission to one CPU: a hundred spinning threads would starve the classmates checked beside it
(numpy runs with one BLAS thread). Standard library only: this file runs inside the sandbox.
"""

from __future__ import annotations

import ctypes
import errno
import platform
import resource
import signal
import struct

X32_SYSCALL_BIT = 0x40000000
SYSCALLS = {
    "x86_64": (0xC000003E, {"clone": 56, "fork": 57, "vfork": 58, "clone3": 435, "ptrace": 101, "process_vm_readv": 310, "process_vm_writev": 311}),
    "aarch64": (0xC00000B7, {"clone": 220, "clone3": 435, "ptrace": 117, "process_vm_readv": 270, "process_vm_writev": 271}),
}
"""Per machine: the audit architecture seccomp reports, and the system calls refused: those that
start a process or a thread, and those that reach into another process (which could be made to
start them)."""

# classic BPF: load word at offset, jump if equal / greater or equal, return
LD_ABS, JEQ, JGE, RET = 0x20, 0x15, 0x35, 0x06
ALLOW, KILL = 0x7FFF0000, 0x80000000
ERRNO = 0x00050000


def set_limits(cpu: float, memory: int, files: int, processes: int) -> None:
    """CPU seconds (the soft limit sends SIGXCPU, which ends the process), address space (bytes),
    open files, processes of this user; no core dumps, no file may grow (writes to files fail)."""
    seconds = max(1, int(cpu + 0.999))
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write over the size limit fails instead of killing
    for limit, value in ((resource.RLIMIT_CPU, (seconds, seconds + 1)), (resource.RLIMIT_AS, (memory, memory)),
                         (resource.RLIMIT_NOFILE, (files, files)), (resource.RLIMIT_NPROC, (processes, processes)),
                         (resource.RLIMIT_CORE, (0, 0)), (resource.RLIMIT_FSIZE, (0, 0))):  # fmt: skip
        resource.setrlimit(limit, value)


def _program(audit_arch: int, numbers: dict[str, int]) -> list[tuple[int, int, int, int]]:
    """The BPF filter as (code, jump if true, jump if false, k) rows."""
    rows: list[tuple] = [
        (LD_ABS, 0, 0, 4),  # seccomp_data.arch
        (JEQ, 1, 0, audit_arch),
        (RET, 0, 0, KILL),  # a foreign system call table (i386 on x86-64): nothing to allow there
        (LD_ABS, 0, 0, 0),  # seccomp_data.nr
    ]
    if audit_arch == SYSCALLS["x86_64"][0]:
        rows.append((JGE, "deny", 0, X32_SYSCALL_BIT))  # the x32 table: the same calls under other numbers
    rows += [(JEQ, "deny", 0, number) for number in numbers.values()]
    labels = {"allow": len(rows), "deny": len(rows) + 1}
    rows += [(RET, 0, 0, ALLOW), (RET, 0, 0, ERRNO | errno.EPERM)]
    jump = lambda target, i: labels[target] - i - 1 if isinstance(target, str) else target  # noqa: E731
    return [(code, jump(jt, i), jump(jf, i), k) for i, (code, jt, jf, k) in enumerate(rows)]


class _Program(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def forbid_new_tasks() -> bool:
    """Install the filter for the rest of this process's life; False where it cannot be had (another
    machine or operating system), and the caller says so."""
    machine = SYSCALLS.get(platform.machine())
    if machine is None or platform.system() != "Linux":
        return False
    rows = _program(*machine)
    code = ctypes.create_string_buffer(b"".join(struct.pack("HBBI", *row) for row in rows))
    program = _Program(len(rows), ctypes.addressof(code))
    libc = ctypes.CDLL(None, use_errno=True)
    pr_set_no_new_privs, pr_set_seccomp, seccomp_mode_filter = 38, 22, 2
    if libc.prctl(pr_set_no_new_privs, 1, 0, 0, 0) != 0:
        return False
    return libc.prctl(pr_set_seccomp, seccomp_mode_filter, ctypes.byref(program), 0, 0) == 0
