#!/usr/bin/env python3
"""Markdown table of the plant fidelity probe (docs/FIDELITY.md): MuJoCo against Rapier.

    python3 docs/scripts/fidelity_table.py MUJOCO.json RAPIER.json [RAPIER_BEFORE.json]

One row per figure. Curves (pulse J, drop curve) are compared as RMS(rapier - mujoco) / (max -
min of MuJoCo's curve) and are inside the band at <= 0.10; the MuJoCo column shows the curve's
swing, the Rapier columns its RMS difference. Scalars are inside at |rapier - mujoco| <=
max(0.25 |mujoco|, floor), the floor keeping near-zero MuJoCo values reachable: 0.05 m/s for
speeds, 1 for flips / falls, 0.2 /s for rates, 5 steps for step counts, 0.005 m for
penetration, 0.02 rad for overshoot and rms figures (none for the drop heights). A figure
missing on the Rapier side counts as outside.
"""

import json
import math
import sys

CURVE_BAND = 0.10
SCALAR_BAND = 0.25

FLOORS = {
    "steps_0_1": 5.0,
    "steps_1": 5.0,
    "fall_step": 5.0,
    "rate": 0.2,
    "trot_speed": 0.05,
    "random_speed": 0.05,
    "speed": 0.05,
    "speed_spread": 0.05,
    "flips": 1.0,
    "falls": 1.0,
    "limit_overshoot": 0.02,
    "pitch_rms": 0.02,
    "track_rms": 0.02,
    "max_penetration": 0.005,
    "trot_penetration": 0.005,
    "penetration": 0.005,
    "min": 0.0,
    "final": 0.0,
}


def get(d, path):
    for k in path:
        if d is None:
            return None
        if isinstance(d, list):
            d = d[k] if isinstance(k, int) and k < len(d) else None
        else:
            d = d.get(k)
    return d


def fmt(v):
    if v is None:
        return "—"
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v)
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 100:
        return "%.1f" % v
    if a >= 1:
        return "%.3g" % v if a < 10 else "%.1f" % v
    return "%.3g" % v


def curve_err(ref, other):
    """RMS(other - ref) / swing(ref), over the common length; (rms, rel)."""
    if ref is None or other is None:
        return None, None
    n = min(len(ref), len(other))
    if n == 0:
        return None, None
    if len(ref) != len(other):
        print(
            "warning: curve lengths differ (%d vs %d), compared over %d"
            % (len(ref), len(other), n),
            file=sys.stderr,
        )
    rms = math.sqrt(sum((other[i] - ref[i]) ** 2 for i in range(n)) / n)
    swing = max(ref) - min(ref)
    return rms, (rms / swing if swing > 0 else math.inf)


def scalar_err(ref, other, floor):
    if ref is None or other is None:
        return None, False
    diff = abs(other - ref)
    rel = diff / abs(ref) if ref != 0 else (0.0 if diff == 0 else math.inf)
    inside = diff <= max(SCALAR_BAND * abs(ref), floor)
    return rel, inside


def rows(mj):
    """(label, kind, path, floor key) for every figure present on the MuJoCo side."""
    out = []
    for seq in ("zero", "trot", "random"):
        for k in ("steps_0_1", "steps_1", "rate"):
            out.append(("divergence %s %s" % (seq, k), "scalar", ("divergence", seq, k), k))
    for k in (
        "trot_speed",
        "random_speed",
        "flips",
        "falls",
        "fall_step",
        "limit_overshoot",
        "max_penetration",
        "trot_penetration",
    ):
        if get(mj, ("open_loop", k)) is not None:
            out.append((k, "scalar", ("open_loop", k), k))
    for j in range(len(mj.get("pulse", []))):
        out.append(("pulse %d: RMS/swing" % j, "curve", ("pulse", j), None))
    out.append(("drop curve: RMS/swing", "curve", ("drop", "curve"), None))
    for k in ("min", "final", "penetration"):
        out.append(("drop %s" % k, "scalar", ("drop", k), k))
    for sigma in ("0", "0.1", "0.3"):
        for k in ("speed", "speed_spread", "pitch_rms", "track_rms"):
            out.append(
                ("closed loop sigma %s %s" % (sigma, k), "scalar", ("closed_loop", sigma, k), k)
            )
    return out


def main():
    if len(sys.argv) not in (3, 4):
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    mj = json.load(open(sys.argv[1]))
    ra = json.load(open(sys.argv[2]))
    before = json.load(open(sys.argv[3])) if len(sys.argv) == 4 else None

    head = ["figure", "MuJoCo"] + (["Rapier before"] if before else []) + [
        "Rapier",
        "rel. error",
        "inside",
    ]
    print("%s (%s)" % (mj.get("family", "?"), mj.get("source", "?")))
    print()
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    n_in = n_all = 0
    for label, kind, path, fk in rows(mj):
        ref = get(mj, path)
        r = get(ra, path)
        if kind == "curve":
            rms, rel = curve_err(ref, r)
            inside = rel is not None and rel <= CURVE_BAND
            cells = ["swing " + fmt(max(ref) - min(ref))]
            if before:
                b_rms, b_rel = curve_err(ref, get(before, path))
                cells.append(
                    "—" if b_rms is None else "%s (%s)" % (fmt(b_rms), fmt(b_rel))
                )
            cells.append("—" if rms is None else fmt(rms))
            cells.append("—" if rel is None else fmt(rel))
        else:
            rel, inside = scalar_err(ref, r, FLOORS[fk])
            cells = [fmt(ref)]
            if before:
                cells.append(fmt(get(before, path)))
            cells.append(fmt(r))
            if rel is None:
                cells.append("—")
            else:
                sign = "+" if r >= ref else "-"
                cells.append("inf" if math.isinf(rel) else "%s%.0f%%" % (sign, 100 * rel))
        cells.append("yes" if inside else "**no**")
        n_all += 1
        n_in += int(bool(inside))
        print("| " + " | ".join([label] + cells) + " |")
    print()
    print("%d of %d figures inside the band" % (n_in, n_all))


if __name__ == "__main__":
    main()
