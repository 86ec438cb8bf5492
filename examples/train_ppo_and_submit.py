"""From ``gymnasium.make`` to a leaderboard submission, end to end.

1. Train a small PPO policy (stable-baselines3) on the benchmark's vector environment, on the
   **train** split only (the held-out split is never seen while learning), with a progress bar.
2. Export the policy's deterministic actor (an MLP) to ONE submission file: its weights travel
   inside the file as a base64, zlib-compressed ``.npz`` constant, so the file's sha256 (what the
   board records and ``verify`` checks) covers them, and the sandbox needs numpy only, not torch.
3. Dry-run it: ``scftc submit FILE --dry-run`` flies it in the sandbox on the public test draw,
   with every check a landing run makes.

Run: ``python examples/train_ppo_and_submit.py --timesteps 200000 --out my_ppo.py`` (the default
budget; needs the ``rl`` extra), with ``--benchmark scftc-v2`` (the reaction-wheel track) or
``--benchmark scftc-v3`` (the agile mission): every version with a gymnasium environment. The test
suite runs it with ``--timesteps 2048 --num-envs 8`` and a tiny dry run: it checks the path, not the
policy's quality (a few minutes of PPO on this task settles nothing; see docs/rl.md).
A submission file may be at most 1 MB (``submission/manifest.py``): about 180 000 float32
parameters after compression and base64.
"""

from __future__ import annotations

import argparse
import base64
import io
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np

TEMPLATE = '''"""{name}: a PPO policy trained on {benchmark}'s train split, exported from stable-baselines3.

Made by examples/train_ppo_and_submit.py ({timesteps} environment steps, seed {seed}). The MLP's
weights are the WEIGHTS constant below (base64 of a zlib-compressed .npz), so this one file is the
whole controller and its sha256 covers them.
"""

import base64
import io
import zlib

import numpy as np

SUBMISSION = {{
    "name": "{name}",
    "version": "1.0.0",
    "authors": ["{author}"],
    "description": "PPO (stable-baselines3 MlpPolicy) trained on the train split; numpy actor.",
    "entry": "PPOPolicy",
    "license": "MIT",
    "benchmark": "{benchmark}",
}}

WEIGHTS = (
{weights}
)


def _load():
    with np.load(io.BytesIO(zlib.decompress(base64.b64decode("".join(WEIGHTS))))) as arrays:
        return [arrays[f"w{{i}}"] for i in range(len(arrays.files) // 2)], [
            arrays[f"b{{i}}"] for i in range(len(arrays.files) // 2)
        ]


class PPOPolicy:
    """Observation -> tanh MLP -> action mean, clipped to [-1, 1] (sb3's deterministic action)."""

    def __init__(self):
        self.weights, self.biases = _load()

    def reset(self, n, context):
        pass

    def act(self, obs):
        x = np.asarray(obs, dtype=np.float64)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            x = x @ w.T.astype(np.float64) + b.astype(np.float64)
            if i < last:
                x = np.tanh(x)
        return np.clip(x, -1.0, 1.0)
'''


def env_ids() -> dict[str, str]:
    """Every registered benchmark version with a gymnasium environment, and that environment's id
    (found through the version registry: a new version with an environment gets the route)."""
    from scftc_cli.versions import get_version, version_names

    return {name: get_version(name).envs[0].id for name in version_names() if get_version(name).envs}


def train(timesteps: int, seed: int, num_envs: int, benchmark: str):
    """A PPO policy trained on ``benchmark``'s train split through ``gymnasium.make_vec``."""
    import gymnasium as gym
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn, TimeRemainingColumn
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecEnv

    import scftc_cli  # noqa: F401  (registers the scftc/AttitudeFTC environments)

    vector = gym.make_vec(env_ids()[benchmark], num_envs=num_envs, vectorization_mode="vector_entry_point")

    class Adapter(VecEnv):
        """gymnasium's VectorEnv (same-step autoreset) seen through sb3's VecEnv interface."""

        def __init__(self) -> None:
            self.venv, self.seed_value = vector, seed  # before VecEnv asks for render_mode
            self.render_mode = None
            super().__init__(num_envs, vector.single_observation_space, vector.single_action_space)

        def reset(self):
            obs, _ = self.venv.reset(seed=self.seed_value)
            return obs

        def step_async(self, actions):
            self.actions = actions

        def step_wait(self):
            obs, reward, terminated, truncated, info = self.venv.step(self.actions)
            done = terminated | truncated
            infos = [{} for _ in range(num_envs)]
            if done.any():
                for i in np.flatnonzero(done):
                    infos[i] = {"terminal_observation": info["final_obs"][i], "TimeLimit.truncated": True}
            return obs, reward.astype(np.float32), done, infos

        def close(self):
            pass

        def get_attr(self, attr_name, indices=None):
            return [getattr(self, attr_name, None)] * num_envs

        def set_attr(self, attr_name, value, indices=None):
            pass

        def env_method(self, method_name, *args, indices=None, **kwargs):
            return [None] * num_envs

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * num_envs

    class Bar(BaseCallback):
        """Environment steps done, on a rich progress bar (stderr); a plain line where stderr is
        not a terminal, so logs show how far training got."""

        def __init__(self, progress: Progress) -> None:
            super().__init__()
            self.progress, self.task = progress, progress.add_task(f"PPO on {benchmark}", total=timesteps)
            self.next_line = time.monotonic() + 10.0

        def _on_step(self) -> bool:
            done = min(self.num_timesteps, timesteps)
            self.progress.update(self.task, completed=done)
            if not self.progress.console.is_terminal and time.monotonic() >= self.next_line:
                print(
                    f"PPO on {benchmark}: {done} of {timesteps} environment steps",
                    file=sys.stderr,
                    flush=True,
                )
                self.next_line = time.monotonic() + 30.0
            return True

    model = PPO("MlpPolicy", Adapter(), n_steps=256, batch_size=256, seed=seed, verbose=0, device="cpu")
    model.set_logger(Logger(folder=None, output_formats=[]))  # no log folder left in /tmp
    columns = [
        "{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    ]
    with Progress(*columns, transient=True) as progress:
        model.learn(total_timesteps=timesteps, callback=Bar(progress))
    print(f"trained {timesteps} environment steps of PPO on {benchmark}'s train split", file=sys.stderr)
    return model


def export(model, name: str, author: str, timesteps: int, seed: int, benchmark: str) -> str:
    """The submission file's text: the actor's layers as a compressed, base64 constant."""
    net, action = model.policy.mlp_extractor.policy_net, model.policy.action_net
    linears = [m for m in net if hasattr(m, "weight")] + [action]
    buf = io.BytesIO()
    np.savez(
        buf,
        **{f"w{i}": m.weight.detach().numpy().astype(np.float32) for i, m in enumerate(linears)},
        **{f"b{i}": m.bias.detach().numpy().astype(np.float32) for i, m in enumerate(linears)},
    )
    blob = base64.b64encode(zlib.compress(buf.getvalue(), 9)).decode()
    lines = "\n".join(f'    "{blob[i : i + 96]}"' for i in range(0, len(blob), 96))
    return TEMPLATE.format(
        name=name, author=author, timesteps=timesteps, seed=seed, weights=lines, benchmark=benchmark
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--benchmark", choices=sorted(env_ids()), default="scftc-v1")
    parser.add_argument("--timesteps", type=int, default=200_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--name", default="my_ppo")
    parser.add_argument("--author", default="you")
    parser.add_argument("--out", type=Path, default=Path("my_ppo.py"))
    parser.add_argument("--dry-run-size", nargs=2, type=int, default=(50, 10), metavar=("FAULTS", "SEEDS"))
    parser.add_argument("--no-dry-run", action="store_true")
    args = parser.parse_args()

    model = train(args.timesteps, args.seed, args.num_envs, args.benchmark)
    args.out.write_text(export(model, args.name, args.author, args.timesteps, args.seed, args.benchmark))
    print(f"wrote {args.out} ({args.out.stat().st_size} bytes)")
    from scftc_cli.versions import get_version

    if not args.no_dry_run and get_version(args.benchmark).draft:
        print(f"no dry run: {args.benchmark} is a draft; its held-out draw is closed until it is frozen")
    elif not args.no_dry_run:
        faults, seeds = args.dry_run_size
        command = [sys.executable, "-m", "scftc_cli", "submit", str(args.out), "--dry-run"]
        command += ["--n-faults", str(faults), "--n-seeds", str(seeds)]
        subprocess.run(command, check=True)


if __name__ == "__main__":
    main()
