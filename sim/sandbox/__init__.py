"""Running untrusted code isolated by the operating system: lab submissions and contest entries.

One `Sandbox` holds one untrusted Python file, run by a small guest program in a process of its
own, inside bubblewrap (user, mount, pid, network namespaces; see `launch`), with kernel limits on
CPU time, memory, open files and output, no way to start processes or threads and none to reach
the kernel's shared state (keyrings, io_uring: `confine`). Host and guest exchange plain data
only, length-prefixed JSON (`wire`): the host sends numbers, strings, lists, numpy arrays in a
fixed layout and read-only records of a dataclass's fields; the guest answers in numbers,
strings and lists alone, read by the host with a reader that accepts nothing else (`reply`);
never pickle, never code.

    from sim.sandbox import Limits, Sandbox, StudentError

    with Sandbox("alice/forward.py", modules=("bots.commands",), limits=Limits(cpu=30)) as box:
        pose = box.call("step", 0.0, 0.0, 0.0, 0.1, 0.2, 0.1, 1.0, timeout=2.0)   # a list back
        h = box.new("Driver", timeout=2.0, waypoints=[[1, 0]], heading=0.0)
        box.method(h, "reset", robot_spec, timeout=2.0)            # dataclasses go as records
        command = box.step(h, 0.01, readings, timeout=0.5)         # ["Twist", v, omega, vy]
        poses = box.feed(h2, "update", [(r,) for r in run_readings], "pose", timeout=20.0)  # one request

- `modules`: the project modules the file may import (what its template imports); they and the
  project modules they import at module level are all of the project it can see. numpy and the
  standard library are always there.
- Every request has its own `timeout` (s). Whatever goes wrong raises `StudentError` (`kind`,
  `detail`, `public` without the request's values); after a timeout, a crash or a malformed
  answer the guest is gone and the next request starts a fresh one (`start()` explicitly).
- `close()` (or leaving the `with`) kills the guest with every process it has and returns when
  they are gone; write results only after it.
- `output`: an excerpt of what the code printed (`take_output()`: since the last call, so that
  each scenario keeps its own); `degraded`: True when it ran without isolation
  (only with `degraded=True`, where bubblewrap is missing: `unavailable()` says why);
  `confined`: True when the filter against new processes and threads holds.
"""

from sim.sandbox.box import Limits, Sandbox, SandboxUnavailable, StudentError
from sim.sandbox.launch import unavailable

__all__ = ["Limits", "Sandbox", "SandboxUnavailable", "StudentError", "unavailable"]
