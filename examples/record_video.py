"""Record a policy's episodes as a video: MP4 through Gymnasium's RecordVideo (moviepy),
or an animated GIF through Pillow.

    python examples/record_video.py --model runs/reach/model.zip --out runs/reach/policy.gif
    python examples/record_video.py --model runs/reach/model.zip --out runs/reach/policy.mp4

The env id and its arguments come from the model's train_config.json (examples/evaluate.py
reads it); ``--random`` records random actions instead of a model. Frames are the env's
``render_mode="rgb_array"`` (offscreen EGL: no display needed).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np

import franka_sim_gym  # noqa: F401  (registers the ids)


def record(
    policy,
    env_id: str,
    env_kwargs: dict,
    out: Path,
    episodes: int = 1,
    seed: int = 0,
    size: tuple[int, int] = (480, 360),
) -> Path:
    """Run ``episodes`` episodes of ``policy(obs) -> action`` and write them to ``out``
    (.gif: Pillow; .mp4: gymnasium.wrappers.RecordVideo, which needs moviepy)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    width, height = size
    env = gym.make(env_id, render_mode="rgb_array", width=width, height=height, **env_kwargs)
    fps = env.metadata["render_fps"]  # the policy rate: one frame per step plays in real time
    if out.suffix == ".mp4":
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp) / "clips"
            video = gym.wrappers.RecordVideo(
                env, str(folder), episode_trigger=lambda _: True, name_prefix="episode"
            )
            for k in range(episodes):
                _run(video, policy, seed + k)
            video.close()
            clips = sorted(folder.glob("episode-episode-*.mp4"))
            if len(clips) == 1:
                clips[0].replace(out)
            else:
                from moviepy import VideoFileClip, concatenate_videoclips

                concatenate_videoclips([VideoFileClip(str(c)) for c in clips]).write_videofile(
                    str(out), logger=None
                )
        return out
    if out.suffix != ".gif":
        raise ValueError(f"--out {out}: expected a .gif or .mp4 file")
    from PIL import Image

    frames: list[np.ndarray] = []
    for k in range(episodes):
        frames += _run(env, policy, seed + k)
    env.close()
    images = [Image.fromarray(f) for f in frames]
    images[0].save(out, save_all=True, append_images=images[1:], duration=1000 // fps, loop=0)
    return out


def _run(env, policy, seed: int) -> list[np.ndarray]:
    """One episode; its frames (the reset's, then one per step)."""
    obs, _ = env.reset(seed=seed)
    frames = [env.render()]
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        frames.append(env.render())
        done = terminated or truncated
    return frames


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, help="an SB3 model.zip (train_sb3.py's)")
    parser.add_argument("--random", action="store_true", help="random actions, no model")
    parser.add_argument("--env-id", default=None)
    parser.add_argument("--out", type=Path, required=True, help="a .gif or .mp4 file")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--size", type=int, nargs=2, default=(480, 360), metavar=("W", "H"))
    args = parser.parse_args(argv)
    if args.random == (args.model is not None):
        parser.error("give --model or --random")
    if args.random:
        env_id, env_kwargs = args.env_id or "FrankaFCICartesianVelocity-v0", {}
        space = gym.make(env_id).action_space
        space.seed(args.seed)

        def policy(obs):
            return space.sample()

    else:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from evaluate import load_model

        model, config = load_model(args.model, env_id=args.env_id)
        env_id, env_kwargs = config["env_id"], config["env_kwargs"]

        def policy(obs):
            return model.predict(obs, deterministic=True)[0]

    path = record(policy, env_id, env_kwargs, args.out, args.episodes, args.seed, args.size)
    print(f"record_video: env_id={env_id} episodes={args.episodes} out={path}")


if __name__ == "__main__":
    main()
