"""`franka-sim-gym run-client -- CMD...`: run an unchanged libfranka program on an ordinary kernel.

libfranka's ``Robot`` constructor with its default ``RealtimeConfig::kEnforce`` (libfranka
``src/robot_impl.cpp``) first asks for SCHED_FIFO at the highest priority ("libfranka:
unable to set realtime scheduling: ...") and then reads ``/sys/kernel/realtime``
(``src/control_tools.cpp``, ``hasRealtimeKernel``): anything but 1 — or no such file,
as on every non-PREEMPT_RT kernel — throws "Running kernel does not have realtime
capabilities." before a byte reaches the server. This wrapper runs CMD in a private
mount namespace where that file reads 1:

* a file holding "1" is bind-mounted over ``/sys/kernel/realtime``; where the kernel has
  no such file, ``/sys/kernel`` is replaced by a tmpfs holding ``realtime`` and a bind
  mount of every original entry (so the rest of ``/sys/kernel`` reads as before);
* with CAP_SYS_ADMIN (root) only the mount namespace is new, so CMD keeps the caller's
  real-time scheduling rights (CAP_SYS_NICE);
* otherwise a user namespace is created too (``unshare --user --map-root-user``; CMD then
  runs as root inside it): there CAP_SYS_NICE does not count, and SCHED_FIFO works only
  with an RLIMIT_RTPRIO of 99 (``ulimit -r``). The wrapper says so before CMD starts.

Nothing changes outside CMD's namespace; the server needs none of this.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import tempfile
from typing import TextIO

#: The file libfranka's hasRealtimeKernel() reads.
REALTIME = "/sys/kernel/realtime"
#: libfranka asks for sched_get_priority_max(SCHED_FIFO): 99 on Linux.
FIFO_PRIORITY = 99
#: Capability bits (linux/capability.h).
CAP_SYS_NICE = 23
CAP_SYS_ADMIN = 21
#: The exit status of the namespace set-up when a mount fails (CMD did not run).
SETUP_FAILED = 125

# Runs inside the new namespaces as `sh -c SCRIPT sh STAGE CMD...`: STAGE is an empty
# directory of the caller's (removed afterwards) that carries the staged mounts.
_SCRIPT = r"""
stage=$1; shift
fail() { echo "franka-sim-gym run-client: $1" >&2; exit 125; }
if [ -e /sys/kernel/realtime ]; then
  echo 1 > "$stage/realtime" || fail "cannot write $stage/realtime"
  mount --bind "$stage/realtime" /sys/kernel/realtime \
    || fail "cannot bind-mount over /sys/kernel/realtime"
else
  mkdir "$stage/kernel" || fail "cannot create $stage/kernel"
  mount --bind /sys/kernel "$stage/kernel" || fail "cannot bind-mount /sys/kernel"
  mount -t tmpfs -o mode=755 franka-sim-gym /sys/kernel \
    || fail "cannot mount a tmpfs over /sys/kernel"
  for entry in "$stage"/kernel/*; do
    name=${entry##*/}
    if [ -d "$entry" ]; then mkdir "/sys/kernel/$name"; else : > "/sys/kernel/$name"; fi
    mount --bind "$entry" "/sys/kernel/$name" 2>/dev/null || true
  done
  echo 1 > /sys/kernel/realtime || fail "cannot write /sys/kernel/realtime"
fi
exec "$@"
"""


def kernel_reads_realtime(path: str = REALTIME) -> bool:
    """Whether ``path`` reads 1, as libfranka's hasRealtimeKernel() reads it."""
    try:
        with open(path) as f:
            return f.read().split()[:1] == ["1"]
    except OSError:
        return False


def has_capability(bit: int) -> bool:
    """Whether this process holds capability ``bit`` (its effective set)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("CapEff:"):
                    return bool(int(line.split()[1], 16) >> bit & 1)
    except OSError:
        pass
    return False


def scheduling_problem(user_namespace: bool) -> str | None:
    """Why SCHED_FIFO at priority 99 would be refused to CMD, or None.

    Outside a user namespace CAP_SYS_NICE grants it; inside one only RLIMIT_RTPRIO does
    (the capability counts in the initial namespace alone).
    """
    soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    if soft == resource.RLIM_INFINITY or soft >= FIFO_PRIORITY:
        return None
    if not user_namespace and has_capability(CAP_SYS_NICE):
        return None
    where = "in a user namespace CAP_SYS_NICE does not count, and " if user_namespace else ""
    return (
        f"real-time scheduling: libfranka's kEnforce asks for SCHED_FIFO priority "
        f"{FIFO_PRIORITY}, which needs root (CAP_SYS_NICE) or an RLIMIT_RTPRIO of "
        f"{FIFO_PRIORITY}; {where}the limit here is {soft}. CMD will fail with 'libfranka: "
        f"unable to set realtime scheduling: Operation not permitted' under kEnforce "
        f"(run as root, raise `ulimit -r` to {FIFO_PRIORITY}, or use "
        f"RealtimeConfig kIgnore)."
    )


def namespace_flags(user_namespace: bool) -> list[str]:
    """unshare(1)'s flags: a mount namespace, in a new user namespace when asked."""
    return ["--user", "--map-root-user", "--mount"] if user_namespace else ["--mount"]


def namespaces_problem(unshare: str | None, flags: list[str]) -> str | None:
    """Why the namespaces cannot be created here (a trial ``unshare FLAGS true``), or None."""
    if unshare is None:
        return "unshare(1) (util-linux) is not installed"
    try:
        trial = subprocess.run(
            [unshare, *flags, "true"], capture_output=True, text=True, timeout=30
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"{unshare} {' '.join(flags)} failed: {exc}"
    if trial.returncode != 0:
        detail = trial.stderr.strip() or f"exit status {trial.returncode}"
        return f"{unshare} {' '.join(flags)} is refused here ({detail})"
    return None


def run_client(
    command: list[str], user_namespace: bool | None = None, stream: TextIO | None = None
) -> int:
    """Run ``command`` where /sys/kernel/realtime reads 1; its exit status.

    ``user_namespace``: None chooses (a user namespace only without CAP_SYS_ADMIN).
    Problems are written to ``stream`` (default stderr): a missing real-time scheduling
    right (CMD still runs), namespaces unavailable (CMD does not run: exit 1).
    """
    out = sys.stderr if stream is None else stream
    if not command:
        print("franka-sim-gym run-client: no command given (run-client -- CMD ...)", file=out)
        return 2
    if user_namespace is None:
        user_namespace = not has_capability(CAP_SYS_ADMIN)
    if kernel_reads_realtime():
        problem = scheduling_problem(False)
        if problem:
            print(f"franka-sim-gym run-client: {problem}", file=out)
        return subprocess.run(command).returncode
    flags = namespace_flags(user_namespace)
    unshare = shutil.which("unshare")
    problem = namespaces_problem(unshare, flags)
    if problem:
        print(
            f"franka-sim-gym run-client: cannot give {command[0]} a /sys/kernel/realtime "
            f"reading 1: {problem}. Namespaces are unavailable: run the client with "
            f"RealtimeConfig kIgnore (pylibfranka RealtimeConfig.kIgnore, franky "
            f"RealtimeConfig.Ignore), or on a PREEMPT_RT kernel.",
            file=out,
        )
        return 1
    problem = scheduling_problem(user_namespace)
    if problem:
        print(f"franka-sim-gym run-client: {problem}", file=out)
    stage = tempfile.mkdtemp(prefix="franka-sim-gym-realtime-")
    try:
        return subprocess.run(
            [unshare, *flags, "sh", "-c", _SCRIPT, "sh", stage, *command]
        ).returncode
    finally:
        # The staged mounts lived in CMD's namespace only: what is left here is empty.
        for name in ("realtime", "kernel"):
            path = os.path.join(stage, name)
            if os.path.isdir(path):
                os.rmdir(path)
            elif os.path.exists(path):
                os.remove(path)
        os.rmdir(stage)
