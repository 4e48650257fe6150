"""Learning curves of several examples/train_sb3.py runs in one figure.

    python examples/plot_curves.py runs/push/eval.csv:"SAC + HER + 50 demos" \
        runs/push_rl/eval.csv:"SAC + HER" --level 0.06:"behaviour cloning" \
        --title FrankaFCIPush-v0 --note "published: ..." --out docs/img/push_demos.png

Each CSV is train_sb3.py's eval.csv (steps, success rate, reflex rate, ...),
train_bc.py's curve.csv (fitting steps, ...: give ``--xlabel``) or one of docs/data's
(samples, ...): its
success rate is drawn solid against samples, its reflex rate dashed in the same colour.
``--level VALUE:LABEL`` draws a horizontal line (a baseline measured once, e.g. the
behaviour-cloning policy or the scripted solver); ``--note`` writes a text under the
axes (the published figures, which are not curves of this env).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path


def read(path: Path) -> tuple[list[float], list[float], list[float]]:
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return (
        [float(r["samples"] if "samples" in r else r["steps"]) for r in rows],
        [float(r["success_rate"]) for r in rows],
        [float(r["reflex_rate"]) for r in rows],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("curves", nargs="+", help="CSV:LABEL")
    parser.add_argument("--level", action="append", default=[], help="VALUE:LABEL")
    parser.add_argument("--title", default="")
    parser.add_argument("--note", default="")
    parser.add_argument(
        "--xlabel",
        default="samples (environment steps)",
        help="the x axis (train_bc.py's curve.csv: fitting steps)",
    )
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    for k, spec in enumerate(args.curves):
        path, _, label = spec.partition(":")
        steps, success, reflex = read(Path(path))
        colour = f"C{k}"
        ax.plot(steps, success, marker="o", ms=3, color=colour, label=f"{label}: success")
        ax.plot(steps, reflex, ls="--", color=colour, alpha=0.7, label=f"{label}: reflexes")
    for k, spec in enumerate(args.level):
        value, _, label = spec.partition(":")
        ax.axhline(float(value), color=f"C{k + len(args.curves)}", ls=":", label=label)
    ax.set_xlabel(args.xlabel)
    ax.set_ylabel("rate over the evaluation episodes")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title(args.title)
    ax.legend(fontsize=7, loc="best")
    if args.note:
        fig.text(0.01, 0.01, args.note, fontsize=7, va="bottom", wrap=True)
        fig.subplots_adjust(bottom=0.25)
    fig.tight_layout(rect=(0, 0.08 if args.note else 0, 1, 1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
