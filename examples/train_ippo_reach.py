"""Independent PPO (one policy shared by every arm) on the clawfleet `reach` task, in plain PyTorch.

Each arm is a PettingZoo agent acting on its own observation; the arms share the policy's weights
(parameter sharing, as in IPPO/MAPPO baselines), so experience from both arms trains one network.
Installs with the `rl` extra (`pip install -e '.[rl]'`); prints a line per iteration and writes the
learning curve (CSV, and a PNG with the random policy's return for comparison).

    python examples/train_ippo_reach.py --minutes 8 --curve docs/learning_curve
"""

from __future__ import annotations

import argparse
import csv
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from fleet.env import parallel_env


@dataclass(frozen=True)
class PPOConfig:
    """PPO's knobs; the defaults learn `reach` with 2 arms in minutes on two cores."""

    steps_per_iteration: int = 1024  # env steps (each gives one sample per arm)
    epochs: int = 8
    minibatch: int = 512
    gamma: float = 0.97
    lam: float = 0.95
    clip: float = 0.2
    learning_rate: float = 3e-4
    entropy: float = 0.0
    hidden: int = 64


class RunningNorm:
    """Observation normalisation by running mean and variance (Welford, batched)."""

    def __init__(self, size: int) -> None:
        self.mean, self.var, self.count = np.zeros(size), np.ones(size), 1e-4

    def update(self, x: np.ndarray) -> None:
        mean, var, n = x.mean(0), x.var(0), len(x)
        delta, total = mean - self.mean, self.count + n
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + var * n + delta**2 * self.count * n / total) / total
        self.count = total

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.clip((x - self.mean) / np.sqrt(self.var + 1e-8), -10, 10)


class ActorCritic(nn.Module):
    """A Gaussian policy (state-independent log std) and a value head, two small MLPs."""

    def __init__(self, obs_size: int, act_size: int, hidden: int) -> None:
        super().__init__()
        self.pi = nn.Sequential(
            nn.Linear(obs_size, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, act_size)
        )
        self.v = nn.Sequential(
            nn.Linear(obs_size, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, 1)
        )
        self.log_std = nn.Parameter(torch.full((act_size,), -0.5))

    def dist(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.pi(obs), self.log_std.exp())


def collect(env, agents, net, norm, steps, state):
    """Roll the shared policy for `steps` env steps; returns per-agent arrays (time x agents) and finished returns."""
    obs, returns_now, finished = state["obs"], state["returns"], []
    buf = {k: [] for k in ("obs", "act", "logp", "rew", "done", "val")}
    for _ in range(steps):
        raw = np.stack([obs[a] for a in agents])
        norm.update(raw)
        x = torch.as_tensor(norm(raw), dtype=torch.float32)
        with torch.no_grad():
            d = net.dist(x)
            act = d.sample()
            logp, val = d.log_prob(act).sum(-1), net.v(x).squeeze(-1)
        obs, rewards, terms, truncs, _ = env.step({a: np.clip(act[i].numpy(), -1, 1) for i, a in enumerate(agents)})
        rew = np.array([rewards[a] for a in agents])
        returns_now += rew
        done = not env.agents
        for k, v in (
            ("obs", x),
            ("act", act),
            ("logp", logp),
            ("rew", torch.as_tensor(rew, dtype=torch.float32)),
            ("done", torch.full((len(agents),), float(done))),
            ("val", val),
        ):
            buf[k].append(v)
        if done:
            finished.append(float(returns_now.mean()))
            obs, _ = env.reset(seed=state["episode"])
            state["episode"] += 1
            returns_now[:] = 0.0
    state["obs"] = obs
    with torch.no_grad():
        last = net.v(torch.as_tensor(norm(np.stack([obs[a] for a in agents])), dtype=torch.float32)).squeeze(-1)
    return {k: torch.stack(v) for k, v in buf.items()}, last, finished


def advantages(batch, last_val, cfg: PPOConfig):
    """Generalised advantage estimation over time, per agent (episodes end by truncation: bootstrap is cut)."""
    rew, val, done = batch["rew"], batch["val"], batch["done"]
    adv, gae = torch.zeros_like(rew), torch.zeros_like(last_val)
    for t in reversed(range(len(rew))):
        next_val = last_val if t == len(rew) - 1 else val[t + 1]
        nonterminal = 1.0 - done[t]
        delta = rew[t] + cfg.gamma * next_val * nonterminal - val[t]
        gae = delta + cfg.gamma * cfg.lam * nonterminal * gae
        adv[t] = gae
    return adv, adv + val


def update(net, opt, batch, adv, ret, cfg: PPOConfig) -> None:
    obs, act, logp_old = (batch[k].flatten(0, 1) for k in ("obs", "act", "logp"))
    adv, ret = adv.flatten(), ret.flatten()
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    for _ in range(cfg.epochs):
        for idx in torch.randperm(len(obs)).split(cfg.minibatch):
            d = net.dist(obs[idx])
            ratio = (d.log_prob(act[idx]).sum(-1) - logp_old[idx]).exp()
            surrogate = torch.min(ratio * adv[idx], ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * adv[idx])
            loss = (
                -surrogate.mean()
                + 0.5 * (net.v(obs[idx]).squeeze(-1) - ret[idx]).pow(2).mean()
                - cfg.entropy * d.entropy().sum(-1).mean()
            )
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 0.5)
            opt.step()


def random_return(arms: int, max_cycles: int, episodes: int = 3) -> float:
    env = parallel_env(n_arms=arms, scenario="reach", action_mode="ee_delta", max_cycles=max_cycles)
    out = []
    for e in range(episodes):
        env.reset(seed=10_000 + e)
        total = 0.0
        while env.agents:
            _, r, _, _, _ = env.step({a: env.action_space(a).sample() for a in env.agents})
            total += float(np.mean(list(r.values())))
        out.append(total)
    env.close()
    return float(np.mean(out))


def train(arms: int, minutes: float, iterations: int | None, max_cycles: int, seed: int, cfg: PPOConfig) -> list[dict]:
    torch.manual_seed(seed)
    env = parallel_env(n_arms=arms, scenario="reach", action_mode="ee_delta", max_cycles=max_cycles)
    agents = list(env.possible_agents)
    obs, _ = env.reset(seed=seed)
    net = ActorCritic(env.observation_space(agents[0]).shape[0], env.action_space(agents[0]).shape[0], cfg.hidden)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.learning_rate)
    norm = RunningNorm(env.observation_space(agents[0]).shape[0])
    state = {"obs": obs, "returns": np.zeros(len(agents)), "episode": seed + 1}
    log, started, recent = [], time.monotonic(), []
    k = 0
    while (iterations is None or k < iterations) and time.monotonic() - started < minutes * 60:
        batch, last, finished = collect(env, agents, net, norm, cfg.steps_per_iteration, state)
        adv, ret = advantages(batch, last, cfg)
        update(net, opt, batch, adv, ret, cfg)
        recent = (recent + finished)[-10:]
        k += 1
        row = {
            "iteration": k,
            "wall_s": round(time.monotonic() - started, 1),
            "agent_steps": k * cfg.steps_per_iteration * len(agents),
            "mean_return": round(float(np.mean(recent)), 3) if recent else None,
        }
        log.append(row)
        print(row, flush=True)
    env.close()
    return log


def write_rows(rows: list[dict], path: Path) -> None:
    """A learning curve's rows as CSV (the columns of the first row)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def save_curve(log: list[dict], baseline: float, stem: Path) -> None:
    write_rows(log, stem.with_suffix(".csv"))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = [(r["wall_s"] / 60, r["mean_return"]) for r in log if r["mean_return"] is not None]
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(*zip(*points), label="IPPO, shared policy (last 10 episodes)")
    ax.axhline(baseline, color="grey", linestyle="--", label="random policy")
    ax.set_xlabel("wall minutes (2 cores)")
    ax.set_ylabel("mean episode return per arm")
    ax.set_title("reach, 2 arms, ee_delta")
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(stem.with_suffix(".png"), dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", type=int, default=2)
    parser.add_argument("--minutes", type=float, default=8.0, help="wall-clock budget")
    parser.add_argument("--iterations", type=int, default=None, help="stop after this many iterations (a smoke run)")
    parser.add_argument("--steps", type=int, default=PPOConfig.steps_per_iteration, help="env steps per iteration")
    parser.add_argument("--max-cycles", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--curve", type=Path, default=None, help="write STEM.csv and STEM.png")
    args = parser.parse_args()
    torch.set_num_threads(1)
    cfg = PPOConfig(steps_per_iteration=args.steps, minibatch=min(PPOConfig.minibatch, args.steps * args.arms))
    log = train(args.arms, args.minutes, args.iterations, args.max_cycles, args.seed, cfg)
    baseline = random_return(args.arms, args.max_cycles)
    print(f"random policy: {baseline:.3f}; last: {log[-1]['mean_return']}")
    if args.curve:
        save_curve(log, baseline, args.curve)


if __name__ == "__main__":
    main()
