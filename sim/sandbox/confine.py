"""What the guest does to itself before the untrusted code runs: resource limits, and no new
processes or threads.

The limits are the kernel's (`resource.setrlimit`): CPU seconds, address space, open files,
processes, no core files and no file growth. A process cannot raise a hard limit again. Process
and thread creation is refused by a seccomp filter (Linux x86-64 and arm64): `fork`, `vfork`,
`clone` and `clone3` fail with EPERM, and so do `ptrace` and `process_vm_readv/writev`, the
kernel's shared state (keyrings, io_uring, BPF, perf) and what a container runtime's default
profile refuses besides (`REFUSED`). This
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
REFUSED = {
    "tasks": ("clone", "fork", "vfork", "clone3", "ptrace", "process_vm_readv", "process_vm_writev", "kcmp", "pidfd_getfd",
              "process_madvise"),
    "kernel state": ("add_key", "request_key", "keyctl", "io_uring_setup", "io_uring_enter", "io_uring_register", "bpf",
                     "perf_event_open", "userfaultfd", "fanotify_init", "syslog", "lookup_dcookie", "mbind", "set_mempolicy",
                     "set_mempolicy_home_node", "get_mempolicy", "move_pages", "migrate_pages"),
    "namespaces and mounts": ("unshare", "setns", "mount", "umount2", "pivot_root", "chroot", "open_tree", "move_mount", "fsopen",
                              "fsconfig", "fsmount", "fspick", "mount_setattr", "name_to_handle_at", "open_by_handle_at"),
    "the machine": ("kexec_load", "kexec_file_load", "init_module", "finit_module", "delete_module", "create_module",
                    "get_kernel_syms", "query_module", "acct", "swapon", "swapoff", "reboot", "settimeofday", "clock_settime",
                    "clock_adjtime", "adjtimex", "quotactl", "quotactl_fd", "nfsservctl", "iopl", "ioperm", "uselib", "ustat",
                    "sysfs", "_sysctl", "vhangup", "sethostname", "setdomainname", "afs_syscall", "tuxcall", "security",
                    "getpmsg", "putpmsg"),
}  # fmt: skip
"""The system calls refused, by why: those that start a process or a thread or reach into another
process (which could be made to start them); those that make or read state the kernel shares
beyond the sandbox (keyrings outlive it and are seen by the next guest of the same user; an
io_uring with SQPOLL is a second kernel thread; BPF, perf and userfaultfd reach into the kernel);
and the rest of what a container runtime's default profile refuses (new namespaces, mounts,
modules, clocks, the machine itself)."""
NUMBERS = {
    "x86_64": {"clone": 56, "fork": 57, "vfork": 58, "clone3": 435, "ptrace": 101, "process_vm_readv": 310, "process_vm_writev": 311,
               "kcmp": 312, "pidfd_getfd": 438, "process_madvise": 440, "add_key": 248, "request_key": 249, "keyctl": 250,
               "io_uring_setup": 425, "io_uring_enter": 426, "io_uring_register": 427, "bpf": 321, "perf_event_open": 298,
               "userfaultfd": 323, "fanotify_init": 300, "syslog": 103, "lookup_dcookie": 212, "mbind": 237, "set_mempolicy": 238,
               "set_mempolicy_home_node": 450, "get_mempolicy": 239, "move_pages": 279, "migrate_pages": 256, "unshare": 272,
               "setns": 308, "mount": 165, "umount2": 166, "pivot_root": 155, "chroot": 161, "open_tree": 428, "move_mount": 429,
               "fsopen": 430, "fsconfig": 431, "fsmount": 432, "fspick": 433, "mount_setattr": 442, "name_to_handle_at": 303,
               "open_by_handle_at": 304, "kexec_load": 246, "kexec_file_load": 320, "init_module": 175, "finit_module": 313,
               "delete_module": 176, "create_module": 174, "get_kernel_syms": 177, "query_module": 178, "acct": 163, "swapon": 167,
               "swapoff": 168, "reboot": 169, "settimeofday": 164, "clock_settime": 227, "clock_adjtime": 305, "adjtimex": 159,
               "quotactl": 179, "quotactl_fd": 443, "nfsservctl": 180, "iopl": 172, "ioperm": 173, "uselib": 134, "ustat": 136,
               "sysfs": 139, "_sysctl": 156, "vhangup": 153, "sethostname": 170, "setdomainname": 171, "afs_syscall": 183,
               "tuxcall": 184, "security": 185, "getpmsg": 181, "putpmsg": 182},
    "aarch64": {"clone": 220, "clone3": 435, "ptrace": 117, "process_vm_readv": 270, "process_vm_writev": 271, "kcmp": 272,
                "pidfd_getfd": 438, "process_madvise": 440, "add_key": 217, "request_key": 218, "keyctl": 219, "io_uring_setup": 425,
                "io_uring_enter": 426, "io_uring_register": 427, "bpf": 280, "perf_event_open": 241, "userfaultfd": 282,
                "fanotify_init": 262, "syslog": 116, "lookup_dcookie": 18, "mbind": 235, "set_mempolicy": 237,
                "set_mempolicy_home_node": 450, "get_mempolicy": 236, "move_pages": 239, "migrate_pages": 238, "unshare": 97,
                "setns": 268, "mount": 40, "umount2": 39, "pivot_root": 41, "chroot": 51, "open_tree": 428, "move_mount": 429,
                "fsopen": 430, "fsconfig": 431, "fsmount": 432, "fspick": 433, "mount_setattr": 442, "name_to_handle_at": 264,
                "open_by_handle_at": 265, "kexec_load": 104, "kexec_file_load": 294, "init_module": 105, "finit_module": 273,
                "delete_module": 106, "acct": 89, "swapon": 224, "swapoff": 225, "reboot": 142, "settimeofday": 170,
                "clock_settime": 112, "clock_adjtime": 266, "adjtimex": 171, "quotactl": 60, "quotactl_fd": 443, "nfsservctl": 42,
                "vhangup": 58, "sethostname": 161, "setdomainname": 162},
}  # fmt: skip
"""Per machine, the number of each refused call that exists there (from the kernel's unistd
headers: asm/unistd_64.h on x86-64, asm-generic/unistd.h on arm64; a test compares them)."""
AUDIT_ARCH = {"x86_64": 0xC000003E, "aarch64": 0xC00000B7}
"""The architecture seccomp reports for each machine's native system calls."""

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
    if audit_arch == AUDIT_ARCH["x86_64"]:
        rows.append((JGE, "deny", 0, X32_SYSCALL_BIT))  # the x32 table: the same calls under other numbers
    rows += [(JEQ, "deny", 0, number) for number in numbers.values()]
    labels = {"allow": len(rows), "deny": len(rows) + 1}
    rows += [(RET, 0, 0, ALLOW), (RET, 0, 0, ERRNO | errno.EPERM)]
    jump = lambda target, i: labels[target] - i - 1 if isinstance(target, str) else target
    return [(code, jump(jt, i), jump(jf, i), k) for i, (code, jt, jf, k) in enumerate(rows)]


class _Program(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def forbid_new_tasks() -> bool:
    """Install the filter for the rest of this process's life; False where it cannot be had (another
    machine or operating system), and the caller says so."""
    machine = platform.machine()
    if machine not in NUMBERS or platform.system() != "Linux":
        return False
    rows = _program(AUDIT_ARCH[machine], NUMBERS[machine])
    code = ctypes.create_string_buffer(b"".join(struct.pack("HBBI", *row) for row in rows))
    program = _Program(len(rows), ctypes.addressof(code))
    libc = ctypes.CDLL(None, use_errno=True)
    pr_set_no_new_privs, pr_set_seccomp, seccomp_mode_filter = 38, 22, 2
    if libc.prctl(pr_set_no_new_privs, 1, 0, 0, 0) != 0:
        return False
    return libc.prctl(pr_set_seccomp, seccomp_mode_filter, ctypes.byref(program), 0, 0) == 0
