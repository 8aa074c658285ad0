"""Golden trajectories of the MuJoCo backend, made with the Python `mujoco` package.

For each robot: Gymnasium's XML (the copy vendored in sim/mujoco/), a fixed start state, fixed
actions for STEPS control steps of frame skip 5, the walker also under fixed walker-dyn factors.
Every step's qpos and qvel are written; `sim/tests/mujoco_golden.rs` replays the same state and
actions through the Rust backend and requires agreement to 1e-6 (in practice the same bits: one
libmujoco, the same calls).

    scripts/fetch-mujoco.sh --python
    .mujoco/venv/bin/python sim/tests/golden/make_mujoco_golden.py
"""

import hashlib
import json
import math
import pathlib
import struct

import mujoco
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
XMLS = HERE.parent.parent / "mujoco"
STEPS = 300
FRAME_SKIP = 5


def f32(x):
    """A value exactly representable in float32 (what the Rust side's f32 actions carry)."""
    return float(np.float32(x))


def f64_bits(x):
    """The IEEE bits of a double: inputs travel as bits, because a decimal parser may round
    differently in the last place and this chaotic system amplifies one ulp within 100 steps."""
    return struct.unpack("<Q", struct.pack("<d", x))[0]


def f32_bits(x):
    return struct.unpack("<I", struct.pack("<f", x))[0]


def actions(nu, steps, dt):
    # A trot-like pattern: each joint a sine of its own phase, amplitude 0.7, with a slow
    # drift so the robot visits contacts and joint limits.
    out = []
    for t in range(steps):
        row = []
        for j in range(nu):
            phase = 2 * math.pi * 1.5 * t * dt + 0.9 * j
            row.append(f32(0.7 * math.sin(phase) + 0.2 * math.sin(0.05 * t + j)))
        out.append(row)
    return out


def walker_factors():  # decimal is exact here: each factor is an f32 parsed as f32
    # walker-dyn factors for the 7 bodies and 6 joints (fixed, within the 1.5^+-3 / 1.3^+-3 ranges).
    return {
        "mass": [f32(1.5 ** (0.9 * math.sin(1.3 * i + 0.2))) for i in range(7)],
        "inertia": [f32(1.5 ** (0.8 * math.cos(0.7 * i + 0.5))) for i in range(7)],
        "damping": [f32(1.3 ** (1.2 * math.sin(0.9 * i + 1.0))) for i in range(6)],
        "friction": [f32(1.5 ** (1.1 * math.cos(1.1 * i + 0.3))) for i in range(7)],
    }


def apply_factors(model, factors):
    # As sim/src/mujoco.rs: bodies 1..=7, dofs 3..9, each geom by its body; then mj_setConst.
    data = mujoco.MjData(model)
    for b in range(1, model.nbody):
        model.body_mass[b] *= factors["mass"][b - 1]
        model.body_inertia[b] *= factors["inertia"][b - 1]
    for j in range(6):
        model.dof_damping[3 + j] *= factors["damping"][j]
    for g in range(model.ngeom):
        body = model.geom_bodyid[g]
        if body >= 1:
            model.geom_friction[g] *= factors["friction"][body - 1]
    mujoco.mj_setConst(model, data)


def trajectory(xml_name, robot, factors=None):
    xml_path = XMLS / xml_name
    xml = xml_path.read_text()
    model = mujoco.MjModel.from_xml_string(xml)
    if factors is not None:
        apply_factors(model, factors)
    data = mujoco.MjData(model)
    qpos0 = [float(q + 0.05 * math.sin(1.7 * i + 0.3)) for i, q in enumerate(model.qpos0)]
    qvel0 = [float(0.2 * math.cos(0.9 * i)) for i in range(model.nv)]
    # Gymnasium's set_state: reset, state, mj_forward.
    mujoco.mj_resetData(model, data)
    data.qpos[:] = qpos0
    data.qvel[:] = qvel0
    mujoco.mj_forward(model, data)
    dt = model.opt.timestep * FRAME_SKIP
    acts = actions(model.nu, STEPS, dt)
    qpos, qvel = [], []
    for a in acts:
        data.ctrl[:] = a
        for _ in range(FRAME_SKIP):
            mujoco.mj_step(model, data)
        qpos.append(data.qpos.tolist())
        qvel.append(data.qvel.tolist())
    return {
        "robot": robot,
        "xml": xml_name,
        "xml_sha256": hashlib.sha256(xml.encode()).hexdigest(),
        "mujoco": mujoco.__version__,
        "frame_skip": FRAME_SKIP,
        "walker_factors": factors,
        "qpos0_bits": [f64_bits(q) for q in qpos0],
        "qvel0_bits": [f64_bits(v) for v in qvel0],
        "action_f32_bits": [[f32_bits(a) for a in row] for row in acts],
        "qpos": qpos,
        "qvel": qvel,
    }


def main():
    cases = [
        ("half_cheetah.xml", "half_cheetah", None, "mujoco-half_cheetah.json"),
        ("walker2d.xml", "walker2d", None, "mujoco-walker2d.json"),
        ("walker2d.xml", "walker2d", walker_factors(), "mujoco-walker2d-dyn.json"),
        ("ant.xml", "ant", None, "mujoco-ant.json"),
    ]
    for xml, robot, factors, out in cases:
        golden = trajectory(xml, robot, factors)
        path = HERE / out
        path.write_text(json.dumps(golden, separators=(",", ":")) + "\n")
        z = golden["qpos"][-1][1 if robot != "ant" else 2]
        print(f"{out}: {STEPS} steps, final x {golden['qpos'][-1][0]:+.3f}, z {z:+.3f}, "
              f"{path.stat().st_size // 1024} KiB")


if __name__ == "__main__":
    main()
