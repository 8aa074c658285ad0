#!/usr/bin/env python3
"""Three-column fidelity table (docs/FIDELITY.md): Python MuJoCo, this project's MuJoCo
backend, and the Rapier plant, on the same probe; each of the two Rust columns marked against
Python MuJoCo with fidelity_table.py's bands.

    python3 docs/scripts/fidelity_table3.py PYTHON.json BACKEND.json RAPIER.json
"""

import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fidelity_table import FLOORS, CURVE_BAND, curve_err, fmt, get, rows, scalar_err  # noqa: E402


def cell(kind, ref, other, floor):
    if kind == "curve":
        rms, rel = curve_err(ref, other)
        inside = rel is not None and rel <= CURVE_BAND
        text = "—" if rms is None else "RMS %s" % fmt(rms)
    else:
        _, inside = scalar_err(ref, other, floor)
        text = fmt(other)
    return text if inside else "**%s**" % text, inside


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    py, mjrs, ra = (json.load(open(p)) for p in sys.argv[1:])
    print("%s (%s | %s | %s)\n" % (py["family"], py["source"], mjrs["source"], ra["source"]))
    print("| figure | Python MuJoCo | MuJoCo backend | Rapier |")
    print("|---|---|---|---|")
    counts = [0, 0]
    total = 0
    for label, kind, path, key in rows(py):
        ref = get(py, path)
        floor = FLOORS.get(key, 0.0) if key else 0.0
        first = "swing %s" % fmt(max(ref) - min(ref)) if kind == "curve" else fmt(ref)
        cells = []
        for i, other in enumerate((mjrs, ra)):
            text, inside = cell(kind, ref, get(other, path), floor)
            counts[i] += int(inside)
            cells.append(text)
        total += 1
        print("| %s | %s | %s | %s |" % (label, first, cells[0], cells[1]))
    print(
        "\nInside the band of Python MuJoCo (bold: outside): MuJoCo backend %d of %d, Rapier %d of %d"
        % (counts[0], total, counts[1], total)
    )


if __name__ == "__main__":
    main()
