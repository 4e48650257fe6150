"""Build the optional C kernels: every ``franka_sim_gym/**/_<name>.c``.

Everything else is in pyproject.toml. Each kernel sits next to the numpy rule it replaces
whole (sim/: the IK solve, the Jacobian at a point and the copies of every robot's
MjData rows, envs/: the libfranka client's filters)
and becomes the extension ``franka_sim_gym.<package>._<name>``; franka_sim_gym/native/ holds
the loader and the shared C header. Most kernels are optional: without a C compiler the
package runs on their numpy reference paths (``franka_sim_gym.native.describe()`` says
which are loaded). ``REQUIRED`` ones hold rules whose only text is C (issue 38: the
joint generators' precedence tables, the velocity envelope, the safety controller's errors
3 and 4 and the torque interface's 34 and 32: fci/limits/_joint.c; the contact estimate,
the wrench at K and the collision levels: fci/_contact.c): without a compiler the install
fails.
"""

from pathlib import Path

from setuptools import Extension, setup

# -ffp-contract=off: no fused multiply-adds, so that each kernel's elementwise arithmetic
# rounds exactly as the numpy reference it replaces (bit-identical, tested).
FLAGS = ["-O2", "-ffp-contract=off", "-fno-fast-math", "-std=c99"]
HEADERS = sorted(p.as_posix() for p in Path("franka_sim_gym").glob("*/_*.h"))
#: Kernels holding rules whose only text is C (issue 38): required, so that a machine
#: that cannot build them fails at install (with the compiler's error), not at import.
REQUIRED = {"franka_sim_gym/fci/limits/_joint.c", "franka_sim_gym/fci/_contact.c"}

KERNELS = [
    Extension(
        ".".join(source.with_suffix("").parts),
        [source.as_posix()],
        include_dirs=["franka_sim_gym/native"],
        depends=HEADERS,
        extra_compile_args=FLAGS,
        optional=source.as_posix() not in REQUIRED,
    )
    for source in sorted(Path("franka_sim_gym").rglob("_*.c"))
]

setup(ext_modules=KERNELS)
