"""Build the optional C kernels (franka_sim_gym/native/_*.c).

Everything else is in pyproject.toml. Each ``franka_sim_gym/native/_<name>.c`` becomes
the extension ``franka_sim_gym.native._<name>``. The kernels are optional: a machine
without a C compiler still installs, and the package runs on its numpy reference paths
(``franka_sim_gym.native`` says which are loaded).
"""

from pathlib import Path

from setuptools import Extension, setup

# -ffp-contract=off: no fused multiply-adds, so that each kernel's elementwise arithmetic
# rounds exactly as the numpy reference it replaces (bit-identical, tested).
FLAGS = ["-O2", "-ffp-contract=off", "-fno-fast-math", "-std=c99"]

KERNELS = [
    Extension(
        f"franka_sim_gym.native.{source.stem}",
        [source.as_posix()],
        depends=["franka_sim_gym/native/_arrays.h"],
        extra_compile_args=FLAGS,
        optional=True,
    )
    for source in sorted(Path("franka_sim_gym/native").glob("_*.c"))
]

setup(ext_modules=KERNELS)
