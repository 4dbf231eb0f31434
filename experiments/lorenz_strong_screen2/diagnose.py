"""Where do a trained Lorenz policy's below-threshold steps fall: start-up transient or later dips?

    python experiments/lorenz_strong_screen2/diagnose.py RUN_DIR [AGENT]

Rolls out 32 deterministic episodes from random initial states (rollout seed 0) and prints the
fraction of steps with |velocity| <= 40 per time window, the dips after step 200 (count, length),
the speed percentiles, the actions during dips, and the lobe switches (sign changes of x).
"""

import sys

import numpy as np

import jaxsimrl

WINDOWS = [(0, 50), (50, 100), (100, 200), (200, 500), (500, 1000), (1000, 2000), (2000, 3000), (3000, 4000)]


def dip_lengths(below: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True in each row (one episode per row)."""
    lengths = []
    for row in below:
        edges = np.diff(np.concatenate([[0], row.astype(int), [0]]))
        lengths.extend(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))
    return np.array(lengths)


def main(run_dir: str, agent: int | None) -> None:
    policy = jaxsimrl.load_policy(run_dir, **({} if agent is None else {"agent": agent}))
    record = policy.rollout(episodes=32, seed=0)
    speed, xyz, action = record["info.speed"], record["state.xyz"], record["action"]
    below = speed <= 40.0
    print(f"fraction above 40: {1 - below.mean():.4f}; mean return {record['reward'].sum(1).mean():,.0f}")
    for lo, hi in WINDOWS:
        share = below[:, lo:hi].sum() / below.sum()
        print(f"steps {lo:4d}-{hi:4d}: below {below[:, lo:hi].mean():.3f} (share of below steps {share:.3f})")
    late = below[:, 200:]
    dips = dip_lengths(late)
    print(f"after step 200: {len(dips) / len(late):.1f} dips per episode, "
          f"length median {np.median(dips):.0f} mean {dips.mean():.2f} max {dips.max()}")
    percentiles = np.percentile(speed[:, 200:], [1, 5, 10, 20, 50]).round(1)
    print("speed percentiles 1/5/10/20/50 after step 200:", percentiles)
    bound = np.asarray(policy.env_params.action_bound)
    in_dips = (action[:, 200:][late] / bound).mean(0).round(2)
    print("mean action / bound in dips (d sigma, d rho, d beta):", in_dips)
    switches = (np.diff(np.sign(xyz[:, 200:, 0]), axis=1) != 0).sum(1)
    print(f"lobe switches per episode after step 200: {switches.mean():.2f}")
    print("x, z range after step 1000:", xyz[:, 1000:, 0].min().round(1), xyz[:, 1000:, 0].max().round(1),
          xyz[:, 1000:, 2].min().round(1), xyz[:, 1000:, 2].max().round(1))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else None)
