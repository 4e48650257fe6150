"""`python -m franka_sim_gym.server [serve flags]`: the same as `franka-sim-gym serve`."""

import argparse
import sys

from .cli import SERVE_EPILOG, add_serve_arguments, serve

if __name__ == "__main__":
    parser = argparse.ArgumentParser(
        prog="python -m franka_sim_gym.server",
        epilog=SERVE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_serve_arguments(parser)
    sys.exit(serve(parser.parse_args()))
