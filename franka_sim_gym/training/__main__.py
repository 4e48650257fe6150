"""``python -m franka_sim_gym.training [ALGO]``: the path of the shipped rl-zoo3 file.

    python -m rl_zoo3.train --algo sac --env FrankaFCI-v0 --gym-packages franka_sim_gym \
        -conf "$(python -m franka_sim_gym.training sac)"
"""

from __future__ import annotations

import sys

from franka_sim_gym.training import hyperparams_file


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    try:
        print(hyperparams_file(args[0] if args else "sac"))
    except ValueError as error:
        sys.exit(str(error))


if __name__ == "__main__":
    main()
