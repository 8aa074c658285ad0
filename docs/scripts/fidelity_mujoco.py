#!/usr/bin/env python3
"""MuJoCo side of the plant fidelity probe defined in docs/FIDELITY.md.

    python3 docs/scripts/fidelity_mujoco.py --family {cheetah,walker,ant} --json OUT [--seeds 30]

Runs every measurement of docs/FIDELITY.md on Gymnasium's own XML (half_cheetah.xml,
walker2d.xml, ant.xml) with the raw `mujoco` API (no Gymnasium env classes) and writes the
JSON that `docs/scripts/fidelity_table.py` compares against the Rapier side.

Conventions (where docs/FIDELITY.md leaves a choice, this is the one taken):
- One numpy default_rng(seed) per seed: reset noise first (qpos noise of size nq, then qvel noise
  of size nv, as Gymnasium draws them), then the random sequence as one (200, n_joints) block
  of U(-1, 1). The same reset state is used for every sequence, for the open-loop statistics and
  for the closed loop of that seed. The closed loop's action noise is a separate
  default_rng(1_000_000 + seed), one standard_normal(n_joints) per control step (drawn for
  sigma = 0 too).
- Every per-step quantity (state, flips, falls, joint-limit excursion, ground penetration,
  torso height, pitch) is measured on the state after control steps k = 1..N, with contacts
  and body poses recomputed for that state (mj_forward, which does not change the
  trajectory), not at the physics substeps. The closed loop's tracking error is the one the
  controller sees: q - q*(k dt) on the state before acting, k = 0..199.
- Rates: medians over the seeds with a finite rate (a twin with d(K) = 0 has none).
- Ground penetration: max over contacts involving the floor geom of max(0, -contact.dist).
- Pulse: torso welded by deleting the root joints from the XML and putting the torso body at
  its rest height + 1 m (cheetah 1.7, walker 2.25, ant init_qpos z 0.55 + 1 = 1.55); rest pose
  joint angles (qpos0; the ant's init_qpos), zero velocity.
- speed_spread: population standard deviation (numpy's default, ddof = 0).
- Drop final: mean of the last round(0.5 / dt) values of the drop curve.
"""

import argparse
import importlib.util
import json
import os
import re
import sys
import time

import mujoco
import numpy as np

STEPS = 200

# MuJoCo's warnings (half_cheetah.xml's deprecated settotalmass, still applied: total mass 14)
# go to stderr instead of a MUJOCO_LOG.TXT in the working directory
mujoco.set_mju_user_warning(lambda msg: print("mujoco warning:", msg, file=sys.stderr))


def assets_dir():
    # importing gymnasium.envs.mujoco needs its rendering extras; finding it does not
    spec = importlib.util.find_spec("gymnasium.envs.mujoco")
    return os.path.join(os.path.dirname(spec.origin), "assets")


def gym_version():
    try:
        from importlib.metadata import version

        return version("gymnasium")
    except Exception:  # pragma: no cover
        import gymnasium

        return gymnasium.__version__


def planar(xml, period, phases, reset):
    """A planar robot's entry: root joints rootx, rootz, rooty; 5 physics steps a control step."""
    return dict(xml=xml, frame_skip=5, root_joints=["rootx", "rootz", "rooty"], planar=True,
                period=period, phases=phases, reset=reset)


FAMILIES = {
    # bthigh, bshin, bfoot (back leg leads by half a period), fthigh, fshin, ffoot
    "cheetah": planar("half_cheetah.xml", 0.5, [np.pi] * 3 + [0.0] * 3, "cheetah"),
    # right leg (thigh, leg, foot) 0, left leg pi
    "walker": planar("walker2d.xml", 0.8, [0.0] * 3 + [np.pi] * 3, "walker"),
    "ant": dict(
        xml="ant.xml",
        frame_skip=5,
        root_joints=["root"],
        planar=False,
        period=0.5,
        # qpos order hip_1, ankle_1, ..., hip_4, ankle_4: hips 0 on legs 1 and 3, pi on 2 and 4,
        # each ankle its hip's + pi / 2
        phases=[0.0, np.pi / 2, np.pi, 1.5 * np.pi, 0.0, np.pi / 2, np.pi, 1.5 * np.pi],
        reset="ant",
    ),
}


class Plant:
    def __init__(self, family):
        self.family = family
        self.cfg = FAMILIES[family]
        path = os.path.join(assets_dir(), self.cfg["xml"])
        with open(path) as f:
            self.xml = f.read()
        self.m = mujoco.MjModel.from_xml_string(self.xml)
        m = self.m
        self.dt = m.opt.timestep * self.cfg["frame_skip"]
        self.torso = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "torso")
        self.floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        # actuated hinge joints in qpos order
        act_joints = [int(m.actuator_trnid[i, 0]) for i in range(m.nu)]
        self.joints = sorted(act_joints, key=lambda j: m.jnt_qposadr[j])
        self.nj = len(self.joints)
        self.qadr = np.array([m.jnt_qposadr[j] for j in self.joints])
        self.vadr = np.array([m.jnt_dofadr[j] for j in self.joints])
        # ctrl[i] = a[perm[i]]: actuator i drives joint number perm[i] (qpos order)
        self.perm = np.array([self.joints.index(j) for j in act_joints])
        self.lo = np.array([m.jnt_range[j, 0] for j in self.joints])
        self.hi = np.array([m.jnt_range[j, 1] for j in self.joints])
        self.mid = 0.5 * (self.lo + self.hi)
        self.half = 0.5 * (self.hi - self.lo)
        # every limited hinge (for the overshoot)
        self.lim = [
            j
            for j in range(m.njnt)
            if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and m.jnt_limited[j]
        ]
        self.lim_adr = np.array([m.jnt_qposadr[j] for j in self.lim])
        self.lim_lo = np.array([m.jnt_range[j, 0] for j in self.lim])
        self.lim_hi = np.array([m.jnt_range[j, 1] for j in self.lim])
        if family == "ant":
            self.rest_qpos = np.array(m.numeric("init_qpos").data, dtype=float)
        else:
            self.rest_qpos = m.qpos0.copy()
        self.data = mujoco.MjData(m)

    # ---- state ------------------------------------------------------------------------------
    def reset(self, rng):
        m, d = self.m, self.data
        mujoco.mj_resetData(m, d)
        kind = self.cfg["reset"]
        if kind == "walker":
            qpos = self.rest_qpos + rng.uniform(-5e-3, 5e-3, size=m.nq)
            qvel = np.zeros(m.nv) + rng.uniform(-5e-3, 5e-3, size=m.nv)
        else:
            qpos = self.rest_qpos + rng.uniform(-0.1, 0.1, size=m.nq)
            qvel = np.zeros(m.nv) + 0.1 * rng.standard_normal(m.nv)
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        mujoco.mj_forward(m, d)

    def reset_rest(self):
        m, d = self.m, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = self.rest_qpos
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)

    def get_state(self):
        d = self.data
        return d.qpos.copy(), d.qvel.copy()

    def set_state(self, qpos, qvel):
        m, d = self.m, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        mujoco.mj_forward(m, d)

    def obs(self):
        d = self.data
        if self.cfg["planar"]:
            return np.concatenate([d.qpos[1:], d.qvel])
        q = d.qpos[2:].copy()
        if q[1] < 0.0:  # quaternion w >= 0
            q[1:5] = -q[1:5]
        return np.concatenate([q, d.qvel])

    def step(self, a):
        """One control step with action a (joint order), clipped to [-1, 1]; recomputes the
        derived quantities (body poses, contacts) for the state reached."""
        m, d = self.m, self.data
        a = np.clip(np.asarray(a, dtype=float), -1.0, 1.0)
        d.ctrl[:] = a[self.perm]
        for _ in range(self.cfg["frame_skip"]):
            mujoco.mj_step(m, d)
        mujoco.mj_forward(m, d)

    def x(self):
        return float(self.data.qpos[0])

    def height(self):
        return float(self.data.xpos[self.torso, 2])

    def upright(self):
        """Planar: pitch (rooty, about +y). Ant: tilt angle of the torso z axis."""
        d = self.data
        if self.cfg["planar"]:
            return float(d.qpos[2])
        return float(np.arccos(np.clip(d.xmat[self.torso, 8], -1.0, 1.0)))

    def flipped(self):
        d = self.data
        if self.cfg["planar"]:
            return abs(float(d.qpos[2])) > np.pi / 2
        return float(d.xmat[self.torso, 8]) < 0.0

    def unhealthy(self):
        # Gymnasium's Walker2d: healthy iff 0.8 < z < 2.0 and -1 < angle < 1
        d = self.data
        z, ang = float(d.qpos[1]), float(d.qpos[2])
        return not (0.8 < z < 2.0 and -1.0 < ang < 1.0)

    def overshoot(self):
        q = self.data.qpos[self.lim_adr]
        ex = np.maximum(np.maximum(q - self.lim_hi, self.lim_lo - q), 0.0)
        return float(ex.max()) if len(ex) else 0.0

    def penetration(self):
        d = self.data
        deepest = 0.0
        for i in range(d.ncon):
            c = d.contact[i]
            if c.geom1 == self.floor or c.geom2 == self.floor:
                deepest = max(deepest, -float(c.dist))
        return deepest

    def joint_q(self):
        return self.data.qpos[self.qadr].copy()

    def joint_qd(self):
        return self.data.qvel[self.vadr].copy()

    # ---- sequences --------------------------------------------------------------------------
    def trot(self, k):
        t = k * self.dt
        return 0.6 * np.sin(2 * np.pi * t / self.cfg["period"] + np.array(self.cfg["phases"]))

    def welded_model(self):
        xml = self.xml
        for name in self.cfg["root_joints"]:
            xml, n = re.subn(r'<joint\b[^>]*\bname="%s"[^>]*/>' % re.escape(name), "", xml)
            assert n == 1, name
        # torso body pos -> rest height + 1 m
        mt = re.search(r'<body\b[^>]*\bname="torso"[^>]*>', xml)
        tag = mt.group(0)
        mp = re.search(r'\bpos="([^"]*)"', tag)
        px, py, pz = (float(v) for v in mp.group(1).split())
        if self.family == "ant":
            rest_z = float(self.rest_qpos[2])  # the free joint puts the torso at init_qpos z
        else:
            rest_z = pz  # the slide joints' qpos0 leave the torso at its body pos
        new_tag = tag.replace(mp.group(0), 'pos="%r %r %r"' % (px, py, rest_z + 1.0))
        xml = xml.replace(tag, new_tag)
        return mujoco.MjModel.from_xml_string(xml)


# ---- measurements -------------------------------------------------------------------------------


def rollout(p, qpos, qvel, actions, twin=False):
    """Open-loop rollout from (qpos, qvel); returns per-step records after steps 1..N."""
    p.set_state(qpos, qvel)
    x0 = p.x()
    rec = dict(s=[], x0=x0, flips=False, unhealthy_step=None, overshoot=0.0, pen=0.0)
    for k in range(len(actions)):
        a = np.array(actions[k], dtype=float)
        if twin and k == 0:
            a = a + 1e-3
        p.step(a)
        rec["s"].append(p.obs())
        rec["flips"] = rec["flips"] or p.flipped()
        if rec["unhealthy_step"] is None and p.unhealthy():
            rec["unhealthy_step"] = k + 1
        rec["overshoot"] = max(rec["overshoot"], p.overshoot())
        rec["pen"] = max(rec["pen"], p.penetration())
    rec["x"] = p.x()
    rec["s"] = np.array(rec["s"])
    return rec


def divergence(p, a, b):
    diff = a["s"] - b["s"]
    mx = np.abs(diff).max(axis=1)
    d = np.linalg.norm(diff, axis=1)

    def first(th):
        idx = np.nonzero(mx > th)[0]
        return int(idx[0] + 1) if len(idx) else STEPS + 1

    K = int(round(1.0 / p.dt))
    rate = np.log(d[K - 1] / d[0]) / ((K - 1) * p.dt)
    return first(0.1), first(1.0), float(rate)


def med(v):
    return float(np.median(np.asarray(v, dtype=float)))


def open_loop(p, seeds):
    div = {s: [] for s in ("zero", "trot", "random")}
    trot_speed, random_speed, flips, falls, fall_step = [], [], 0, 0, []
    overshoot, pen, trot_pen = [], [], []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        p.reset(rng)
        qpos, qvel = p.get_state()
        rand = rng.uniform(-1.0, 1.0, size=(STEPS, p.nj))
        seqs = {
            "zero": np.zeros((STEPS, p.nj)),
            "trot": np.array([p.trot(k) for k in range(STEPS)]),
            "random": rand,
        }
        for name, acts in seqs.items():
            a = rollout(p, qpos, qvel, acts)
            b = rollout(p, qpos, qvel, acts, twin=True)
            div[name].append(divergence(p, a, b))
            speed = (a["x"] - a["x0"]) / (STEPS * p.dt)
            if name == "trot":
                trot_speed.append(speed)
                trot_pen.append(a["pen"])
            elif name == "random":
                random_speed.append(speed)
                flips += int(a["flips"])
                if a["unhealthy_step"] is not None:
                    falls += 1
                fall_step.append(a["unhealthy_step"] or STEPS + 1)
                overshoot.append(a["overshoot"])
                pen.append(a["pen"])
    out_div = {}
    for name, v in div.items():
        v = np.array(v, dtype=float)
        rates = v[np.isfinite(v[:, 2]), 2]  # a twin that never parts (d = 0) has no rate
        out_div[name] = {
            "steps_0_1": med(v[:, 0]),
            "steps_1": med(v[:, 1]),
            "rate": med(rates),
        }
    walker = p.family == "walker"
    ol = {
        "trot_speed": med(trot_speed),
        "random_speed": med(random_speed),
        "flips": int(flips),
        "falls": int(falls) if walker else None,
        "fall_step": med(fall_step) if walker else None,
        "limit_overshoot": med(overshoot),
        "max_penetration": med(pen),
        "trot_penetration": med(trot_pen),
    }
    return out_div, ol


def pulse(p):
    m = p.welded_model()
    d = mujoco.MjData(m)
    # the welded model keeps the joints (and actuators) in the same order, less the root ones
    act_joints = [int(m.actuator_trnid[i, 0]) for i in range(m.nu)]
    joints = sorted(act_joints, key=lambda j: m.jnt_qposadr[j])
    names = [m.joint(j).name for j in joints]
    assert names == [p.m.joint(j).name for j in p.joints], names
    perm = np.array([joints.index(j) for j in act_joints])
    qadr = np.array([m.jnt_qposadr[j] for j in joints])
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    rest = p.rest_qpos[p.qadr]
    n = int(round(1.0 / p.dt))
    curves = []
    for J in range(p.nj):
        mujoco.mj_resetData(m, d)
        d.qpos[qadr] = rest
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        sign = 1.0 if p.mid[J] >= 0.0 else -1.0
        curve = []
        for k in range(n):
            a = np.zeros(p.nj)
            if k == 0:
                a[J] = sign
            d.ctrl[:] = a[perm]
            for _ in range(p.cfg["frame_skip"]):
                mujoco.mj_step(m, d)
            mujoco.mj_forward(m, d)
            for i in range(d.ncon):
                c = d.contact[i]
                assert c.geom1 != floor and c.geom2 != floor, "welded robot touches the floor"
            curve.append(float(d.qpos[qadr[J]]))
        curves.append(curve)
    return curves


def drop(p):
    p.reset_rest()
    n = int(round(2.0 / p.dt))
    curve, pen = [], 0.0
    for _ in range(n):
        p.step(np.zeros(p.nj))
        curve.append(p.height())
        pen = max(pen, p.penetration())
    last = int(round(0.5 / p.dt))
    return {
        "curve": curve,
        "min": float(min(curve)),
        "final": float(np.mean(curve[-last:])),
        "penetration": float(pen),
    }


def closed_loop(p, seeds):
    out = {}
    for sigma, key in ((0.0, "0"), (0.1, "0.1"), (0.3, "0.3")):
        speeds, pitch, track = [], [], []
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            p.reset(rng)
            noise = np.random.default_rng(1_000_000 + seed)
            x0 = p.x()
            up2, err2 = [], []
            for k in range(STEPS):
                t = k * p.dt
                qs = p.mid + 0.5 * p.half * np.sin(
                    2 * np.pi * t / p.cfg["period"] + np.array(p.cfg["phases"])
                )
                q, qd = p.joint_q(), p.joint_qd()
                # tracking error as the controller sees it: steps k = 0..199, before acting
                err2.extend(((q - qs) ** 2).tolist())
                a = np.clip(2.0 * (qs - q) / p.half - 0.1 * qd, -1.0, 1.0)
                a = np.clip(a + sigma * noise.standard_normal(p.nj), -1.0, 1.0)
                p.step(a)
                # pitch / tilt after each step, k = 1..200
                up2.append(p.upright() ** 2)
            speeds.append((p.x() - x0) / (STEPS * p.dt))
            pitch.append(np.sqrt(np.mean(up2)))
            track.append(np.sqrt(np.mean(err2)))
        out[key] = {
            "speed": med(speeds),
            "speed_spread": float(np.std(speeds)),
            "pitch_rms": med(pitch),
            "track_rms": med(track),
        }
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", required=True, choices=sorted(FAMILIES))
    ap.add_argument("--json", required=True)
    ap.add_argument("--seeds", type=int, default=30)
    args = ap.parse_args()

    t0 = time.time()
    p = Plant(args.family)
    div, ol = open_loop(p, args.seeds)
    res = {
        "family": args.family,
        "source": "mujoco %s, gymnasium %s, %s"
        % (mujoco.__version__, gym_version(), p.cfg["xml"]),
        "dt": float(round(p.dt, 10)),
        "seeds": int(args.seeds),
        "steps": STEPS,
        "divergence": div,
        "open_loop": ol,
        "pulse": pulse(p),
        "drop": drop(p),
        "closed_loop": closed_loop(p, args.seeds),
    }
    d = os.path.dirname(args.json)
    if d:
        os.makedirs(d, exist_ok=True)
    with open(args.json, "w") as f:
        json.dump(res, f, indent=1)
        f.write("\n")
    print("%s: wrote %s in %.1f s" % (args.family, args.json, time.time() - t0))


if __name__ == "__main__":
    main()
