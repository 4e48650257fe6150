"""``--smoke``, which every benchmark here takes: a run of a second or so through every
row of its table, so that `make test` runs each script as documented
(tests/commands/test_benchmarks.py). Its figures mean nothing; the defaults measure."""

from __future__ import annotations

import argparse


def parse_args(parser: argparse.ArgumentParser, **short) -> argparse.Namespace:
    """``parser.parse_args()`` with ``--smoke`` added: with it, each option named in
    ``short`` (by its dest) takes the value given there."""
    shown = ", ".join(
        f"--{name.replace('_', '-')}" + ("" if value is True else f" {value}")
        for name, value in short.items()
    )
    parser.add_argument(
        "--smoke",
        action="store_true",
        help=f"a short run through every row, not a measurement (make test): {shown}",
    )
    args = parser.parse_args()
    if args.smoke:
        for name, value in short.items():
            setattr(args, name, value)
    return args
