"""`franka-sim-gym run-client`: CMD runs where /sys/kernel/realtime reads 1 (a private mount
namespace), the rest of /sys/kernel as it was, nothing changed outside; clear words when
namespaces or real-time scheduling are unavailable."""

from __future__ import annotations

import io
import os
import shutil
import sys
import tempfile

import pytest

from franka_sim_gym.server import run_client as rc
from franka_sim_gym.server.cli import main

READ = "print(open('/sys/kernel/realtime').read().strip())"


def available(user_namespace: bool) -> None:
    """Skip, naming why, where this machine cannot create the namespaces."""
    problem = rc.namespaces_problem(shutil.which("unshare"), rc.namespace_flags(user_namespace))
    if problem:
        pytest.skip(f"namespaces unavailable on this machine: {problem}")


@pytest.mark.parametrize("user_namespace", [False, True], ids=["mount-ns", "user-ns"])
def test_a_python_child_reads_1_and_the_rest_of_sys_kernel_is_unchanged(
    user_namespace, capfd, tmp_path, monkeypatch
):
    if not user_namespace and not rc.has_capability(rc.CAP_SYS_ADMIN):
        pytest.skip("a mount namespace alone needs CAP_SYS_ADMIN (not held here)")
    available(user_namespace)
    # The staging directory goes to a directory of this test's own (a parallel run's
    # would share the system's temporary directory).
    stage_root = tmp_path / "stage"
    stage_root.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(stage_root))
    before = rc.kernel_reads_realtime()
    listing = tmp_path / "listing"
    write = f"open({str(listing)!r}, 'w').write(repr(top_level()))"
    code = f"{READ}\n{TOP_LEVEL}\n{write}"
    status = rc.run_client([sys.executable, "-c", code], user_namespace=user_namespace)
    assert status == 0
    assert capfd.readouterr().out.strip().splitlines()[-1] == "1"
    inside = eval(listing.read_text())  # noqa: S307 (our own repr of a dict)
    namespace: dict = {}
    exec(TOP_LEVEL, namespace)  # noqa: S102 (the same function, outside)
    outside = namespace["top_level"]()
    inside.pop("realtime", None)
    outside.pop("realtime", None)
    assert inside == outside  # every entry there, every readable file reading the same
    assert any(value is not None for value in outside.values())
    # Nothing changed outside CMD's namespace, and the staging directory is gone.
    assert rc.kernel_reads_realtime() is before
    assert os.listdir(stage_root) == []


#: The top level of /sys/kernel: each entry, and the text of each small readable file.
TOP_LEVEL = """
import os
def top_level():
    out = {}
    for name in sorted(os.listdir('/sys/kernel')):
        path = os.path.join('/sys/kernel', name)
        try:
            out[name] = open(path, 'rb').read(200) if os.path.isfile(path) else None
        except OSError:
            out[name] = None
    return out
"""


def test_the_cli_passes_the_childs_exit_status():
    available(not rc.has_capability(rc.CAP_SYS_ADMIN))
    code = "import sys; sys.exit(0 if open('/sys/kernel/realtime').read().strip() == '1' else 9)"
    assert main(["run-client", "--", sys.executable, "-c", code]) == 0
    assert main(["run-client", "--", sys.executable, "-c", "import sys; sys.exit(3)"]) == 3


def test_a_new_user_namespace_only_without_cap_sys_admin():
    """With CAP_SYS_ADMIN only the mount namespace is new, so CMD keeps the caller's
    scheduling rights; without it CMD runs in a user namespace of its own."""
    new_user_namespace = not rc.has_capability(rc.CAP_SYS_ADMIN)
    available(new_user_namespace)
    mine = os.readlink("/proc/self/ns/user")
    same = f"import os, sys; sys.exit(0 if os.readlink('/proc/self/ns/user') == {mine!r} else 4)"
    assert main(["run-client", "--", sys.executable, "-c", same]) == (
        4 if new_user_namespace else 0
    )


def test_no_command_is_refused():
    out = io.StringIO()
    assert rc.run_client([], stream=out) == 2
    assert "no command given" in out.getvalue()


def test_an_rtprio_limit_of_99_grants_fifo_99_in_a_user_namespace(monkeypatch):
    import resource

    monkeypatch.setattr(resource, "getrlimit", lambda which: (rc.FIFO_PRIORITY, 100))
    assert rc.scheduling_problem(user_namespace=True) is None
    monkeypatch.setattr(resource, "getrlimit", lambda which: (rc.FIFO_PRIORITY - 1, 100))
    assert "the limit here is 98" in rc.scheduling_problem(user_namespace=True)


def test_in_a_user_namespace_the_scheduling_right_is_named_when_missing():
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    problem = rc.scheduling_problem(user_namespace=True)
    if soft == resource.RLIM_INFINITY or soft >= rc.FIFO_PRIORITY:
        assert problem is None
    else:
        assert "CAP_SYS_NICE" in problem and "RLIMIT_RTPRIO" in problem
        assert "unable to set realtime scheduling" in problem
    if rc.has_capability(rc.CAP_SYS_NICE):
        assert rc.scheduling_problem(user_namespace=False) is None


def test_without_unshare_it_says_namespaces_are_unavailable_and_runs_nothing(monkeypatch, tmp_path):
    if rc.kernel_reads_realtime():
        pytest.skip("this kernel reads /sys/kernel/realtime = 1: nothing to wrap")
    monkeypatch.setattr(rc.shutil, "which", lambda name: None)
    marker = tmp_path / "ran"
    out = io.StringIO()
    status = rc.run_client(
        [sys.executable, "-c", f"open({str(marker)!r}, 'w').close()"], stream=out
    )
    assert status == 1 and not marker.exists()
    assert "Namespaces are unavailable" in out.getvalue()
    assert "unshare(1) (util-linux) is not installed" in out.getvalue()
    assert "kIgnore" in out.getvalue()
