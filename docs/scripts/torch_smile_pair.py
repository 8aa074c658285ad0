"""A whole SMILe update pair in PyTorch, doing the work `smile bench --workload pair` does.

`docs/bench/pytorch/torch_reference.py` times a SAC step and a discriminator step on their own.
A SMILe update pair (trainer/src/algo/smile.rs, `Smile::update_pair`) does more than those two
steps: the SAC batch's reward comes from the discriminator (a forward pass of the 3 x 512 net
over the SAC batch's 1024 rows, about 1.2 GFLOP), both halves encode contexts of whole demos
(k in 1..=4 demos of 50 transitions per task under the cheetah recipe, where the `disc`
workload encodes 4 x 16), and both draw their rows from replays and demos. This script is that
pair, written the plain PyTorch way, so the two sides are compared on equal work. It follows
`docs/configs/authors-cv-smile.toml` (cheetah-vel, the authors' recipe):

  disc side  8 distinct tasks; per task a context of k ~ U{1..4} demos x 50 transitions of
             [s, a, s'] (17 + 6 + 17) -> encoder 2 x 256 -> r 64, mean over steps, sum over
             demos, head 64 -> 64 -> 64 -> (mu, log sigma - 2) of z 64, z sampled; 128 expert
             and 128 policy rows [s, a] per task (gathered by index) with the task's z;
             discriminator 3 x 512 on [s, a, z], logit clamped to +-10, BCE with logits +
             10 x gradient penalty on interpolated rows (z detached there); Adam (0, 0.999) for
             the discriminator, Adam (0.9, 0.999) for the encoder and head.
  SAC side   8 distinct tasks, fresh contexts encoded without gradient, z sampled; 128 replay
             rows per task (gathered); reward = 24 x clamp(D([s, a, z]), -10, 10) without
             gradient; SAC v2 with twin Q 3 x 256 and Polyak targets (tau 0.005), policy
             3 x 256 (tanh-Gaussian), temperature fixed at 1, 1e-3 x (mean mu^2 + mean
             log_std^2) on the actor loss.

The two halves run one after the other (ours with one learner thread does the same; with two,
ours runs them side by side, PyTorch splits each operator over its intra-op threads). Data is
random and made once; per-step sampling is index gathers. Each pair is timed on its own with
perf_counter_ns; the median is reported as one JSON line, as torch_reference.py does.

    .venv-torch/bin/python docs/scripts/torch_smile_pair.py --threads 1 2 --iters 40 --warmup 5

Compare with `smile bench --workload pair --config docs/configs/authors-cv-smile.toml ...`'s
`updates_only_per_pair_us` (its pairs without the rollouts; PyTorch here has no simulator).
"""
import argparse, json, math, os, sys

import torch
import torch.nn as nn
import torch.nn.functional as F

# The timing loop is torch_reference.py's (one per call, median and percentiles).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench", "pytorch"))
from torch_reference import bench  # noqa: E402

LR = 3e-4
OBS, ACT = 17, 6  # sim/src/planar.rs OBS_DIM; the cheetah's six joints


def mlp(d_in, widths, d_out):
    mods, d = [], d_in
    for h in widths:
        mods += [nn.Linear(d, h), nn.ReLU()]
        d = h
    return nn.Sequential(*mods, nn.Linear(d, d_out))


def make_pair(a):
    T, DT, L, N = a.tasks, a.demos_per_task, a.demo_len, a.per_task
    zd, rd = a.z_dim, a.r_dim
    # The networks (authors' cheetah widths).
    enc = mlp(2 * OBS + ACT, [a.enc_hidden] * 2, rd)
    head = mlp(rd, [a.head_hidden] * 2, 2 * zd)
    disc = mlp(OBS + ACT + zd, [a.disc_hidden] * a.layers, 1)
    d_in = OBS + zd
    q1, q2 = mlp(d_in + ACT, [a.sac_hidden] * a.layers, 1), mlp(d_in + ACT, [a.sac_hidden] * a.layers, 1)
    q1_t, q2_t = mlp(d_in + ACT, [a.sac_hidden] * a.layers, 1), mlp(d_in + ACT, [a.sac_hidden] * a.layers, 1)
    q1_t.load_state_dict(q1.state_dict()); q2_t.load_state_dict(q2.state_dict())
    pi = mlp(d_in, [a.sac_hidden] * a.layers, 2 * ACT)
    q_params = list(q1.parameters()) + list(q2.parameters())
    t_params = list(q1_t.parameters()) + list(q2_t.parameters())
    pi_params = list(pi.parameters())
    disc_opt = torch.optim.Adam(disc.parameters(), lr=LR, betas=(0.0, 0.999))
    enc_opt = torch.optim.Adam(list(enc.parameters()) + list(head.parameters()), lr=LR)
    q_opt, pi_opt = torch.optim.Adam(q_params, lr=LR), torch.optim.Adam(pi_params, lr=LR)
    # The data: per task, DT demos of L transitions [s, a, s'] and a replay of R rows.
    R = a.replay_rows
    demos = torch.randn(a.train_tasks, DT, L, 2 * OBS + ACT)
    rep_obs, rep_nobs = torch.randn(a.train_tasks, R, OBS), torch.randn(a.train_tasks, R, OBS)
    rep_act, rep_done = torch.rand(a.train_tasks, R, ACT) * 2 - 1, torch.zeros(a.train_tasks, R, 1)
    gamma, tau, alpha, scale, reg = 0.99, 0.005, 1.0, a.reward_scale, 1e-3
    gen = torch.Generator().manual_seed(a.seed)

    def tasks():
        return torch.randperm(a.train_tasks, generator=gen)[:T]

    def context(ts):
        """Encoder input rows and the aggregation matrix A (tasks x rows, m_j / T_j)."""
        rows, blocks = [], []
        for t in ts.tolist():
            k = int(torch.randint(1, a.max_context + 1, (1,), generator=gen))
            which = torch.randperm(DT, generator=gen)[:k]
            rows.append(demos[t, which].reshape(k * L, -1))
            blocks.append(torch.full((1, k * L), 1.0 / L))
        return torch.cat(rows), torch.block_diag(*blocks)

    def posterior(x, agg):
        mu, log_sig = head(agg @ enc(x)).chunk(2, dim=-1)
        return mu, log_sig - 2.0

    def z_sample(mu, log_sig):
        return mu + log_sig.exp() * torch.randn(mu.shape, generator=gen)

    def rows(ts, n):
        """n replay rows of each task: (obs, act, next_obs, done), gathered."""
        idx = torch.randint(0, R, (len(ts), n), generator=gen)
        g = lambda buf: torch.stack([buf[t][i] for t, i in zip(ts.tolist(), idx)]).reshape(len(ts) * n, -1)
        return g(rep_obs), g(rep_act), g(rep_nobs), g(rep_done)

    def demo_rows(ts, n):
        out = []
        for t in ts.tolist():
            j, s = torch.randint(0, DT, (n,), generator=gen), torch.randint(0, L, (n,), generator=gen)
            out.append(demos[t, j, s, :OBS + ACT])
        return torch.cat(out)

    def logit(x):
        return disc(x).clamp(-10.0, 10.0)

    def disc_step():
        ts = tasks()
        cx, agg = context(ts)
        z = z_sample(*posterior(cx, agg))                      # (T, zd), gradient into the encoder
        zr = z.repeat_interleave(N, dim=0)                     # (T N, zd)
        x_e = demo_rows(ts, N)
        o, act, _, _ = rows(ts, N)
        x_p = torch.cat([o, act], -1)
        l_e, l_p = logit(torch.cat([x_e, zr], -1)), logit(torch.cat([x_p, zr], -1))
        bce = 0.5 * (F.softplus(-l_e).mean() + F.softplus(l_p).mean())
        u = torch.rand(T * N, 1, generator=gen)
        xi = (u * x_e + (1 - u) * x_p).requires_grad_(True)
        d_i = logit(torch.cat([xi, zr.detach()], -1))
        (g,) = torch.autograd.grad(d_i.sum(), xi, create_graph=True)
        gp = (g.norm(2, dim=-1) - 1).pow(2).mean()
        loss = bce + 10.0 * gp
        disc_opt.zero_grad(); enc_opt.zero_grad(); loss.backward(); disc_opt.step(); enc_opt.step()

    def sample(o):  # tanh-Gaussian, reparameterised: (action, log_prob, mu, log_std)
        mu, log_std = pi(o).chunk(2, dim=-1)
        log_std = log_std.clamp(-20.0, 2.0)
        eps = torch.randn(mu.shape, generator=gen)
        u = mu + log_std.exp() * eps
        logp = (-0.5 * eps.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1, keepdim=True)
        logp = logp - (2 * (math.log(2) - u - F.softplus(-2 * u))).sum(-1, keepdim=True)
        return torch.tanh(u), logp, mu, log_std

    def q_min(n1, n2, o, x):
        ox = torch.cat([o, x], -1)
        return torch.min(n1(ox), n2(ox))

    def sac_step():
        ts = tasks()
        with torch.no_grad():
            cx, agg = context(ts)
            zr = z_sample(*posterior(cx, agg)).repeat_interleave(a.sac_per_task, dim=0)
            o, act, no, done = rows(ts, a.sac_per_task)
            rew = scale * logit(torch.cat([o, act, zr], -1))
            obs, nobs = torch.cat([o, zr], -1), torch.cat([no, zr], -1)
            na_, nlogp, _, _ = sample(nobs)
            y = rew + gamma * (1 - done) * (q_min(q1_t, q2_t, nobs, na_) - alpha * nlogp)
        oa = torch.cat([obs, act], -1)
        q_loss = F.mse_loss(q1(oa), y) + F.mse_loss(q2(oa), y)
        q_opt.zero_grad(); q_loss.backward(); q_opt.step()
        new_a, logp, mu, log_std = sample(obs)
        pi_loss = (alpha * logp - q_min(q1, q2, obs, new_a)).mean()
        pi_loss = pi_loss + reg * (mu.pow(2).mean() + log_std.pow(2).mean())
        pi_opt.zero_grad(); pi_loss.backward(inputs=pi_params); pi_opt.step()
        with torch.no_grad():
            torch._foreach_lerp_(t_params, q_params, tau)

    def pair():
        disc_step()
        sac_step()
    return pair


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--threads", nargs="+", type=int, default=[1, 2])
    p.add_argument("--iters", type=int, default=40)
    p.add_argument("--warmup", type=int, default=5)
    # The shapes (whole numbers), the authors' cheetah recipe by default.
    for flag, default, help in [
        ("--layers", 3, "hidden layers of disc, Qs and policy"),
        ("--disc-hidden", 512, None), ("--sac-hidden", 256, None), ("--enc-hidden", 256, None),
        ("--head-hidden", 64, None), ("--r-dim", 64, None), ("--z-dim", 64, None),
        ("--tasks", 8, "tasks per batch"),
        ("--train-tasks", 100, "tasks to draw from"),
        ("--per-task", 128, "disc expert (and policy) rows per task"),
        ("--sac-per-task", 128, None), ("--demos-per-task", 4, None),
        ("--demo-len", 50, "transitions per demo (1000 steps, sub 20)"),
        ("--max-context", 4, None), ("--replay-rows", 5000, None),
    ]:
        p.add_argument(flag, type=int, default=default, help=help)
    p.add_argument("--reward-scale", type=float, default=24.0)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    load_before, results = os.getloadavg(), []
    for t in a.threads:
        torch.set_num_threads(t)
        torch.manual_seed(a.seed)
        results.append({"workload": "pair", "threads": t, **bench(make_pair(a), a.warmup, a.iters, "pairs_per_s", 2)})
    print(json.dumps({"torch": torch.__version__, "iters": a.iters, "warmup": a.warmup,
                      "args": vars(a), "loadavg_before": load_before,
                      "loadavg_after": os.getloadavg(), "results": results}))


if __name__ == "__main__":
    main()
