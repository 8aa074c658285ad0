"""ONNX export parity with onnxruntime: z and actions against the trainer's.

    smile export --policy runs/pg-smile --format onnx --contexts demos/pg-test.safetensors -o runs/pg-smile/onnx
    python3 docs/scripts/onnx_parity.py runs/pg-smile/onnx [more export dirs ...] [--tol 1e-5] [--json OUT]

Each directory is what `smile export --format onnx` wrote: encoder.onnx, policy.onnx, onnx.json
and reference.safetensors (the trainer's z and deterministic actions on the held-out contexts,
each context padded and masked as a runtime gets it). The script runs both graphs with
onnxruntime on raw inputs (the normalisation is inside the graphs), compares, prints one line
per directory and exits 1 if any max |difference| exceeds --tol.

Needs `pip install onnxruntime numpy`; the safetensors file is read with numpy alone.
"""
import argparse
import json
import os
import struct
import sys

import numpy as np
import onnxruntime as ort


def read_safetensors(path):
    """{name: float32 array} and the header metadata of a safetensors file."""
    with open(path, "rb") as f:
        data = f.read()
    (n,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + n])
    meta = header.pop("__metadata__", {})
    base = 8 + n
    out = {}
    for name, info in header.items():
        if info["dtype"] != "F32":
            raise SystemExit(f"{path}: tensor {name} is {info['dtype']}, expected F32")
        lo, hi = info["data_offsets"]
        out[name] = np.frombuffer(data[base + lo : base + hi], dtype="<f4").reshape(info["shape"])
    return out, meta


def session(path):
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    return ort.InferenceSession(path, sess_options=opts, providers=["CPUExecutionProvider"])


def parity(d):
    meta = json.load(open(os.path.join(d, "onnx.json")))
    enc = session(os.path.join(d, meta["encoder"]["file"]))
    pol = session(os.path.join(d, meta["policy"]["file"]))
    ref_info = meta.get("reference")
    if not ref_info:
        raise SystemExit(f"{d}: no reference in onnx.json (export with --contexts)")
    ref, _ = read_safetensors(os.path.join(d, ref_info["file"]))
    ci = [i["name"] for i in meta["encoder"]["inputs"]]
    pi = [i["name"] for i in meta["policy"]["inputs"]]
    z_name = meta["encoder"]["outputs"][0]["name"]
    a_name = meta["policy"]["outputs"][0]["name"]
    zmax = amax = asame = zabs = 0.0
    actions = 0
    for i in range(ref_info["contexts"]):
        ctx, mask = ref[f"{i}.context"], ref[f"{i}.mask"]
        (z,) = enc.run([z_name], {ci[0]: ctx, ci[1]: mask})
        z_ref = ref[f"{i}.z"]
        assert z.shape == z_ref.shape, (z.shape, z_ref.shape)
        zmax = max(zmax, float(np.abs(z - z_ref).max()))
        zabs = max(zabs, float(np.abs(z_ref).max()))
        obs, a_ref = ref[f"{i}.observation"], ref[f"{i}.action"]
        rows = obs.shape[0]
        (a,) = pol.run([a_name], {pi[0]: obs, pi[1]: np.repeat(z, rows, axis=0)})
        (a2,) = pol.run([a_name], {pi[0]: obs, pi[1]: np.repeat(z_ref, rows, axis=0)})
        amax = max(amax, float(np.abs(a - a_ref).max()))
        asame = max(asame, float(np.abs(a2 - a_ref).max()))
        actions += rows
    return {
        "dir": d,
        "family": meta["family"],
        "algo": meta["algo"],
        "opset": meta["opset"],
        "contexts": ref_info["contexts"],
        "actions": actions,
        "z_max_abs_diff": zmax,
        "max_abs_z": zabs,
        "action_max_abs_diff": amax,
        "action_max_abs_diff_same_z": asame,
    }


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dirs", nargs="+", help="directories written by smile export --format onnx")
    p.add_argument("--tol", type=float, default=1e-5, help="largest max |difference| accepted")
    p.add_argument("--json", help="also write the figures to this JSON file")
    a = p.parse_args()
    print(f"onnxruntime {ort.__version__}, numpy {np.__version__}")
    rows, bad = [], False
    for d in a.dirs:
        r = parity(d)
        rows.append(r)
        ok = max(r["z_max_abs_diff"], r["action_max_abs_diff"], r["action_max_abs_diff_same_z"]) <= a.tol
        bad |= not ok
        print(
            f"{r['family']:<12} {r['algo']:<16} contexts {r['contexts']:>3} actions {r['actions']:>6}: "
            f"z max |diff| {r['z_max_abs_diff']:.2e} (max |z| {r['max_abs_z']:.2f}), "
            f"action max |diff| {r['action_max_abs_diff']:.2e} end to end, "
            f"{r['action_max_abs_diff_same_z']:.2e} on the trainer's z  {'ok' if ok else 'OVER ' + str(a.tol)}"
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"onnxruntime": ort.__version__, "tol": a.tol, "rows": rows}, f, indent=2)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
